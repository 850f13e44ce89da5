// HTTP transport: an async Boost.Beast listener (plain or TLS) and per-connection sessions that hand whole requests
// to a handler.
#pragma once

#include "server/tls_context.h"

#include <boost/asio/io_context.hpp>
#include <boost/asio/ip/tcp.hpp>
#include <boost/asio/thread_pool.hpp>
#include <boost/beast/http.hpp>

#include <chrono>
#include <cstddef>
#include <functional>
#include <memory>
#include <optional>
#include <string>

namespace tessera::server {

namespace http = boost::beast::http;

/// A whole HTTP request as the handler sees it.
using HttpRequest = http::request<http::string_body>;
/// A whole HTTP response.
using HttpResponse = http::response<http::string_body>;

/// A JSON error response `{"error": text}` with the given status (bytes that are not UTF-8 become U+FFFD).
HttpResponse json_error(http::status status, const std::string& text, unsigned version = 11);

/// The application behind the transport.
class HttpHandler {
 public:
  virtual ~HttpHandler() = default;
  /// The largest body accepted for a request with this header (larger ones get 413).
  virtual std::size_t body_limit(const http::request_header<>& header) = 0;
  /// An answer to send at once, before the body is read (e.g. 401 for a missing token), or nothing to read on.
  virtual std::optional<HttpResponse> early_response(const http::request_header<>& /*header*/) noexcept { return std::nullopt; }
  /// Answers a request; runs on the handler pool and must not throw.
  virtual HttpResponse handle(HttpRequest&& request) noexcept = 0;
  /// Where an answer given later goes; call it exactly once, from any thread.
  using Reply = std::function<void(HttpResponse)>;
  /// Answers a request now or later (on another pool): the transport calls this on the handler pool. The default
  /// answers at once with handle().
  virtual void handle_async(HttpRequest&& request, Reply reply) noexcept { reply(handle(std::move(request))); }
};

/// Transport settings.
struct HttpServerOptions {
  std::string host = "127.0.0.1";                      ///< Address to bind.
  unsigned short port = 0;                             ///< Port (0: any free one).
  std::chrono::milliseconds read_timeout{30'000};      ///< A whole request (or keep-alive idle time) must fit in it.
  std::size_t header_limit = 64 * 1024;                ///< Largest request header (larger ones get 431).
  std::size_t max_connections = 1024;                  ///< Open connections; more are answered 503 and closed.
  TlsServerFiles tls;                                  ///< Certificate files (none: plain HTTP).
};

/// Accepts connections and runs one session per connection (each on its own strand); requests are answered on a
/// separate handler pool so slow handlers never block the network threads. With TLS, the handshake is part of the
/// first request: it must finish within the read timeout and its connection counts against the connection limit.
class HttpServer {
 public:
  /// Reads the TLS files (if any), binds and listens (throws std::runtime_error naming the file or address on
  /// failure); call start() to accept.
  HttpServer(boost::asio::io_context& ioc, boost::asio::thread_pool& handlers, HttpHandler& handler, HttpServerOptions options);
  ~HttpServer();
  HttpServer(const HttpServer&) = delete;
  HttpServer& operator=(const HttpServer&) = delete;

  /// The bound address (with the real port when 0 was asked for).
  boost::asio::ip::tcp::endpoint endpoint() const;
  /// Starts accepting connections.
  void start();
  /// Stops accepting, closes idle connections, and lets in-flight requests finish (their connections then close).
  void shutdown();
  /// Reads the TLS files again for connections accepted from now on (open connections keep their session); on
  /// failure throws std::runtime_error and keeps serving with the previous certificate. A no-op without TLS.
  void reload_tls();
  /// True when the listener speaks TLS.
  bool tls() const;

  struct State;  ///< Shared with sessions (opaque).

 private:
  std::shared_ptr<State> state_;
};

}  // namespace tessera::server
