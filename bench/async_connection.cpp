#include "bench/async_connection.h"

#include "client/http_message.h"

#include <boost/asio/redirect_error.hpp>
#include <boost/asio/use_awaitable.hpp>
#include <boost/beast/core/error.hpp>
#include <boost/beast/http/read.hpp>
#include <boost/beast/http/span_body.hpp>
#include <boost/beast/http/string_body.hpp>
#include <boost/beast/http/write.hpp>
#include <poll.h>

namespace tessera::bench {

namespace asio = boost::asio;
namespace beast = boost::beast;
namespace http = boost::beast::http;
using boost::system::error_code;
using client::TransportError;

AsyncConnection::AsyncConnection(asio::any_io_executor executor, client::HttpUrl url,
                                 asio::ip::tcp::resolver::results_type endpoints, client::HttpTimeouts timeouts)
    : url_(std::move(url)), endpoints_(std::move(endpoints)), timeouts_(timeouts), stream_(std::move(executor)) {
  if (url_.tls) throw std::invalid_argument(url_.to_string() + ": the simulated workers speak plain HTTP only");
}

bool AsyncConnection::peer_closed() {
  pollfd p{};
  p.fd = stream_.socket().native_handle();
  p.events = POLLIN;
  return ::poll(&p, 1, 0) != 0;
}

void AsyncConnection::close() {
  error_code ignored;
  stream_.socket().shutdown(asio::ip::tcp::socket::shutdown_both, ignored);
  stream_.close();
  buffer_.clear();
  open_ = false;
}

asio::awaitable<void> AsyncConnection::connect(const std::string& what) {
  if (open_) co_return;
  buffer_.clear();
  error_code ec;
  stream_.expires_after(timeouts_.connect);
  co_await stream_.async_connect(endpoints_, asio::redirect_error(asio::use_awaitable, ec));
  if (ec) {
    close();
    throw TransportError(what + ": cannot connect: " + client::describe_error(ec, timeouts_.connect));
  }
  // As HttpClient: without TCP_NODELAY a request's last segment waits for the server's delayed ACK.
  stream_.socket().set_option(asio::ip::tcp::no_delay(true), ec);
  open_ = true;
}

asio::awaitable<client::HttpResponse> AsyncConnection::send(const client::HttpRequest& request, std::string_view body) {
  const std::string what = request.method + " " + url_.to_string() + request.target;
  const http::verb verb = http::string_to_verb(request.method);
  if (verb == http::verb::unknown) throw TransportError(what + ": unknown method");
  http::request<http::span_body<const char>> writable{client::request_header(url_, token_, request, verb)};
  writable.body() = {body.data(), body.size()};
  writable.keep_alive(true);
  writable.prepare_payload();
  const http::request<http::span_body<const char>>& req = writable;
  const bool idempotent = client::is_idempotent(verb);

  for (int attempt = 0;; ++attempt) {
    if (open_ && peer_closed()) close();
    const bool reused = open_;
    co_await connect(what);

    error_code ec;
    stream_.expires_after(timeouts_.write);
    co_await http::async_write(stream_, req, asio::redirect_error(asio::use_awaitable, ec));
    if (ec) {
      close();
      if (reused && attempt == 0 && ec != beast::error::timeout) continue;
      throw TransportError(what + ": cannot send the request: " + client::describe_error(ec, timeouts_.write));
    }

    http::response_parser<http::string_body> parser;
    parser.body_limit(client::kMaxResponseBytes);
    if (verb == http::verb::head) parser.skip(true);
    stream_.expires_after(timeouts_.read);
    co_await http::async_read(stream_, buffer_, parser, asio::redirect_error(asio::use_awaitable, ec));
    if (ec) {
      const bool got_some = parser.got_some();
      close();
      if (reused && attempt == 0 && !got_some && client::is_stale_connection(ec)) {
        if (idempotent) continue;
        throw TransportError(what + ": the server closed the connection without an answer (" + ec.message() +
                             "); the request may or may not have been carried out");
      }
      throw TransportError(what + ": cannot read the response: " + client::describe_error(ec, timeouts_.read));
    }
    stream_.expires_never();

    auto res = parser.release();
    client::HttpResponse out = client::response_head(res);
    out.body = std::move(res.body());
    if (!res.keep_alive()) close();
    co_return out;
  }
}

}  // namespace tessera::bench
