// A small synchronous HTTP/1.1 client (Boost.Beast, plain or TLS) with connect, write and read timeouts.
#pragma once

#include "client/tls_client_context.h"

#include <chrono>
#include <cstdint>
#include <map>
#include <memory>
#include <optional>
#include <stdexcept>
#include <string>
#include <string_view>
#include <vector>

namespace tessera::farm {

/// The request did not complete: cannot resolve, connect, hand-shake, send or receive, or a timeout. An answer with an
/// HTTP error status is not one: that is an HttpResponse with the status.
struct TransportError : std::runtime_error {
  using std::runtime_error::runtime_error;
};

/// The parts of an http:// or https:// URL the client needs.
struct HttpUrl {
  std::string host;       ///< Host name or address, e.g. "127.0.0.1".
  std::string port = "80";  ///< Port as text.
  std::string base_path;  ///< Path prefix without a trailing slash (usually empty).
  bool tls = false;       ///< https: TLS with the server's certificate verified.

  /// "http[s]://host:port" + base_path, for messages.
  std::string to_string() const;
};

/// Parses "http[s]://host[:port][/prefix]" (a bare "host:port" is plain HTTP; https defaults to port 443); throws
/// std::invalid_argument with the reason for anything else (other schemes, empty host, bad port).
HttpUrl parse_http_url(std::string_view url);

/// How long each phase of a request may take.
struct HttpTimeouts {
  std::chrono::milliseconds connect{3000};  ///< Connecting (and the TLS handshake); names are resolved first, unbounded.
  std::chrono::milliseconds write{30000};   ///< Sending the whole request.
  std::chrono::milliseconds read{30000};    ///< Receiving the whole response.
};

/// One HTTP request.
struct HttpRequest {
  std::string method = "GET";   ///< GET, HEAD, POST, PUT or DELETE.
  std::string target = "/";     ///< Path and query, appended to the URL's base path.
  std::string body;             ///< Request body (sent with Content-Length when non-empty or for POST/PUT).
  std::string content_type;     ///< Content-Type of the body, if any.
  std::map<std::string, std::string> headers;  ///< Further request headers.
};

/// A received response.
struct HttpResponse {
  int status = 0;      ///< Status code, e.g. 200.
  std::string body;    ///< Body bytes (empty for HEAD).
  std::map<std::string, std::string> headers;  ///< Header fields, names lowercased.

  /// The header's value, or "" when absent; name is case-insensitive.
  std::string header(std::string_view name) const;
  /// The "error" text of a JSON error body, else the body itself (shortened), else "HTTP <status>".
  std::string error_text() const;
};

/// A connection to one server, reused across requests (keep-alive) and reopened when the server closed it.
/// For https:// URLs every connection verifies the server's certificate chain and that it names url.host (DNS name
/// or IP address); a failure is a TransportError saying why, never a fallback to plain HTTP or to no verification.
/// Not thread-safe: give each thread its own client.
class HttpClient {
 public:
  /// A client for url; connects lazily on the first request. TLS files are for https:// URLs only: naming one with
  /// an http:// URL, or an unusable file, throws std::invalid_argument.
  explicit HttpClient(HttpUrl url, HttpTimeouts timeouts = {}, uint64_t max_response_bytes = uint64_t(2) << 30,
                      const ClientTlsFiles& tls = {});
  ~HttpClient();
  HttpClient(const HttpClient&) = delete;
  HttpClient& operator=(const HttpClient&) = delete;

  /// Sends the request and reads the whole response; throws TransportError (naming method, URL and cause) on transport
  /// failures and timeouts. A request on a reused connection that the server had closed is retried once on a fresh one.
  HttpResponse send(const HttpRequest& request);
  /// Shorthand for send() with a method, target and optional JSON body.
  HttpResponse send(std::string method, std::string target, std::string body = {},
                    std::string content_type = "application/json");
  /// Sends "Authorization: Bearer <token>" with every request from now on ("" sends none).
  void set_bearer_token(std::string token) { token_ = std::move(token); }
  /// Closes the connection (the next request opens a new one).
  void close();
  /// The server this client talks to.
  const HttpUrl& url() const { return url_; }

 private:
  struct Impl;
  HttpUrl url_;
  std::string token_;
  std::unique_ptr<Impl> impl_;
};

}  // namespace tessera::farm
