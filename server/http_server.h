// HTTP transport: an async Boost.Beast listener (plain or TLS) and per-connection sessions that hand whole requests
// to a handler and write its answer, whole or as a stream of chunks.
#pragma once

#include "server/peer_limits.h"
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
#include <utility>

namespace tessera::server {

namespace http = boost::beast::http;

/// A whole HTTP request as the handler sees it.
using HttpRequest = http::request<http::string_body>;
/// A whole HTTP response.
using HttpResponse = http::response<http::string_body>;

/// A JSON error response `{"error": text}` with the given status (bytes that are not UTF-8 become U+FFFD).
HttpResponse json_error(http::status status, const std::string& text, unsigned version = 11);

/// A response body written as it is produced (e.g. Server-Sent Events), after a header sent at once. The transport
/// calls start() once, then next() on the connection's strand whenever ready() was called and no write is in flight,
/// and stop() once when the stream ends for any reason (last chunk, client gone, write timeout, server shutdown).
class BodyStream {
 public:
  /// What to write now.
  struct Chunk {
    std::string text;   ///< Bytes to write (empty: nothing yet).
    bool last = false;  ///< The body ends after these bytes.
  };
  virtual ~BodyStream() = default;
  /// Starts the stream; `ready` may be called from any thread (it never blocks) whenever next() has something.
  virtual void start(std::function<void()> ready) = 0;
  /// The bytes to write now.
  virtual Chunk next() = 0;
  /// The stream ended; no more calls follow.
  virtual void stop() = 0;
  /// Written when nothing else was for the server's stream_idle time, so idle proxies keep the connection (empty: none).
  virtual std::string idle_text() const { return {}; }
};

/// A handler's answer: a whole response, or (with `stream`) a header whose body the stream writes. A streamed answer
/// ends its connection; over HTTP/1.1 it is sent chunked.
struct HttpReply {
  HttpReply() = default;
  /// A whole response, or with `body`, a header whose body the stream writes (under the header's Content-Length when
  /// it has one).
  HttpReply(HttpResponse res, std::shared_ptr<BodyStream> body = nullptr)  // NOLINT(google-explicit-constructor)
      : response(std::move(res)), stream(std::move(body)) {}
  HttpResponse response;               ///< The response (its header only, when streamed).
  std::shared_ptr<BodyStream> stream;  ///< The body, when streamed.
};

/// A request header field the transport sets on every request (one a client sent is removed first): the peer's
/// network address.
inline constexpr std::string_view kPeerAddressField = "Tessera-Peer-Address";
/// A request header field the transport sets on every request of a TLS connection whose client presented a verified
/// certificate (one a client sent is removed first): the certificate's subject common name.
inline constexpr std::string_view kClientCertNameField = "Tessera-Client-Cert-CN";

/// The application behind the transport.
class HttpHandler {
 public:
  virtual ~HttpHandler() = default;
  /// The largest body accepted for a request with this header (larger ones get 413).
  virtual std::size_t body_limit(const http::request_header<>& header) = 0;
  /// True when the header carries a credential the server accepts (always, when none is required): the connection
  /// is then no longer an anonymous one (PeerLimitOptions).
  virtual bool authenticated(const http::request_header<>& /*header*/) noexcept { return true; }
  /// An answer to send at once, before the body is read (e.g. 401 for a missing token), or nothing to read on.
  virtual std::optional<HttpResponse> early_response(const http::request_header<>& /*header*/) noexcept { return std::nullopt; }
  /// Answers a request; runs on the handler pool and must not throw.
  virtual HttpResponse handle(HttpRequest&& request) noexcept = 0;
  /// Answers a request, possibly with a streamed body; runs on the handler pool.
  virtual HttpReply reply(HttpRequest&& request) noexcept { return {handle(std::move(request)), nullptr}; }
  /// Where an answer given later goes; call it exactly once, from any thread.
  using Reply = std::function<void(HttpReply)>;
  /// Answers a request now or later (on another pool): the transport calls this on the handler pool. The default
  /// answers at once with reply().
  virtual void handle_async(HttpRequest&& request, Reply done) noexcept { done(reply(std::move(request))); }
};

/// Transport settings.
struct HttpServerOptions {
  std::string host = "127.0.0.1";                      ///< Address to bind.
  unsigned short port = 0;                             ///< Port (0: any free one).
  int listen_fd = -1;  ///< A listening TCP socket to serve on instead of binding host:port (it becomes the server's).
  std::chrono::milliseconds read_timeout{30'000};      ///< A whole request (or keep-alive idle time) must fit in it.
  std::size_t header_limit = 64 * 1024;                ///< Largest request header (larger ones get 431).
  std::size_t max_connections = 1024;                  ///< Open connections; more are answered 503 and closed.
  std::chrono::milliseconds stream_idle{15'000};       ///< A streamed body writes its idle text after this long quiet.
  PeerLimitOptions peers;                              ///< Limits on peers before they show a credential.
  TlsServerFiles tls;                                  ///< Certificate files (none: plain HTTP).
};

/// Accepts connections and runs one session per connection (each on its own strand); requests are answered on a
/// separate handler pool so slow handlers never block the network threads. With TLS, the handshake is part of the
/// first request: it must finish within the read timeout and its connection counts against the connection limit.
/// A streamed body has no read timeout; each of its writes must finish within the read timeout (a client that stops
/// reading is closed), and a client that closes its side ends the stream at once.
/// The address a listening TCP socket is bound to ("127.0.0.1", "::1", ...); throws std::runtime_error when `fd` is
/// not an open, listening TCP socket.
std::string listening_address(int fd);

class HttpServer {
 public:
  /// Reads the TLS files (if any), binds and listens, or takes over options.listen_fd (throws std::runtime_error
  /// naming the file or address on failure); call start() to accept.
  HttpServer(boost::asio::io_context& ioc, boost::asio::thread_pool& handlers, HttpHandler& handler, HttpServerOptions options);
  ~HttpServer();
  HttpServer(const HttpServer&) = delete;
  HttpServer& operator=(const HttpServer&) = delete;

  /// The bound address (with the real port when 0 was asked for).
  boost::asio::ip::tcp::endpoint endpoint() const;
  /// Starts accepting connections.
  void start();
  /// Stops accepting, closes idle connections, ends streamed bodies, and lets in-flight requests finish (their
  /// connections then close).
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
