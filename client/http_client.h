// A small synchronous HTTP/1.1 client (Boost.Beast, plain or TLS) with connect, write and read timeouts.
#pragma once

#include "client/tls_client_context.h"

#include <chrono>
#include <cstdint>
#include <functional>
#include <map>
#include <memory>
#include <optional>
#include <stdexcept>
#include <string>
#include <string_view>
#include <vector>

namespace tessera::client {

/// The request did not complete: cannot resolve, connect, hand-shake, send or receive, or a timeout. An answer with an
/// HTTP error status is not one: that is an HttpResponse with the status.
struct TransportError : std::runtime_error {
  using std::runtime_error::runtime_error;
};

/// The caller's `interrupted` said to give up while the request waited (see HttpClient::send): the connection was
/// closed, and the request may or may not have been carried out.
struct RequestInterrupted : std::runtime_error {
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

/// The largest answer body a client reads unless told otherwise (2 GiB).
inline constexpr uint64_t kMaxResponseBytes = uint64_t(2) << 30;

/// One HTTP request.
struct HttpRequest {
  std::string method = "GET";   ///< GET, HEAD, POST, PUT or DELETE.
  std::string target = "/";     ///< Path and query, appended to the URL's base path.
  std::string body;             ///< Request body (sent with Content-Length when non-empty or for POST/PUT).
  std::string content_type;     ///< Content-Type of the body, if any.
  std::map<std::string, std::string> headers;  ///< Further request headers.
};

/// A request of method to target with body, of content_type when the body is not empty (what
/// HttpClient::send(method, target, body, content_type) sends).
HttpRequest make_request(std::string method, std::string target, std::string body = {},
                         std::string content_type = "application/json");

/// A received response.
struct HttpResponse {
  int status = 0;      ///< Status code, e.g. 200.
  std::string body;    ///< Body bytes (empty for HEAD).
  std::map<std::string, std::string> headers;  ///< Header fields, names lowercased.

  /// The header's value, or "" when absent; name is case-insensitive.
  std::string header(std::string_view name) const;
  /// The "error" text of a JSON error body, else the body itself (shortened), else "HTTP <status>".
  std::string error_text() const;
  /// A server error, 408 or 429: the same request may succeed later.
  bool retryable() const { return status >= 500 || status == 408 || status == 429; }
};

/// A connection to one server, reused across requests (keep-alive) and reopened when the server closed it.
/// For https:// URLs every connection verifies the server's certificate chain and that it names url.host (DNS name
/// or IP address); a failure is a TransportError saying why, never a fallback to plain HTTP or to no verification.
/// Not thread-safe: give each thread its own client.
class HttpClient {
 public:
  /// A client for url; connects lazily on the first request. TLS files are for https:// URLs only: naming one with
  /// an http:// URL, or an unusable file, throws std::invalid_argument.
  explicit HttpClient(HttpUrl url, HttpTimeouts timeouts = {}, uint64_t max_response_bytes = kMaxResponseBytes,
                      const ClientTlsFiles& tls = {});
  ~HttpClient();
  HttpClient(const HttpClient&) = delete;
  HttpClient& operator=(const HttpClient&) = delete;

  /// Sends the request and reads the whole response; throws TransportError (naming method, URL and cause) on transport
  /// failures and timeouts. A kept-alive connection the server has closed is replaced before sending; a request
  /// that could not be written on a reused connection goes once more on a fresh one, and so does a GET, HEAD, PUT,
  /// DELETE or OPTIONS whose answer did not start (a POST or PATCH then throws: it may have been carried out).
  HttpResponse send(const HttpRequest& request);
  /// As send(request), asking `interrupted` every 100 ms while the request is under way (e.g. a lease request the
  /// server holds for work); true closes the connection and throws RequestInterrupted.
  HttpResponse send(const HttpRequest& request, const std::function<bool()>& interrupted);
  /// Sends the request on a connection of its own and reads the answer's header. For a 200 answer, calls on_data
  /// once with an empty view when the header has arrived (the stream is open), then with each piece of the body as
  /// it arrives, until on_data returns false or the body ends; a quiet spell longer than `idle` is an TransportError.
  /// Other answers are returned whole (body read within the read timeout) without calling on_data. While waiting
  /// for bytes, `stop` is asked every 100 ms; true ends the stream. The connection is closed afterwards. Throws
  /// TransportError on transport failures.
  HttpResponse stream(const HttpRequest& request, std::chrono::milliseconds idle,
                      const std::function<bool(std::string_view)>& on_data, const std::function<bool()>& stop = {});
  /// A new client for the same server with the same timeouts, TLS settings and token (e.g. to read a stream on
  /// one while sending requests on the other).
  std::unique_ptr<HttpClient> another() const;
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
  HttpClient(HttpUrl url, std::unique_ptr<Impl> impl, std::string token);
  void connect(const std::string& what);                  // opens the connection (and TLS) unless open
  HttpUrl url_;
  std::string token_;
  std::unique_ptr<Impl> impl_;
};

}  // namespace tessera::client
