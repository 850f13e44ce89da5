#include "server/webhook_post.h"

#include <boost/asio/as_tuple.hpp>
#include <boost/asio/co_spawn.hpp>
#include <boost/asio/ip/tcp.hpp>
#include <boost/asio/ssl.hpp>
#include <boost/asio/use_awaitable.hpp>
#include <boost/beast/core.hpp>
#include <boost/beast/http.hpp>
#include <boost/beast/ssl.hpp>

#include <openssl/ssl.h>

namespace tessera::server {

namespace {

namespace asio = boost::asio;
namespace beast = boost::beast;
namespace bhttp = beast::http;
using asio::use_awaitable;

bhttp::request<bhttp::string_body> make_request(const WebhookUrl& url, const std::string& body,
                                                const std::vector<std::pair<std::string, std::string>>& headers) {
  bhttp::request<bhttp::string_body> req{bhttp::verb::post, url.target, 11};
  req.set(bhttp::field::host, url.host);
  req.set(bhttp::field::user_agent, "tessera-webhook");
  req.set(bhttp::field::content_type, "application/json");
  for (const auto& [name, value] : headers) req.set(name, value);
  req.body() = body;
  req.prepare_payload();
  return req;
}

// Writes the request and reads the answer's status (its body, up to 64 KiB, is dropped).
template <class Stream>
asio::awaitable<int> exchange(Stream& stream, bhttp::request<bhttp::string_body>& req) {
  co_await bhttp::async_write(stream, req, use_awaitable);
  beast::flat_buffer buffer;
  bhttp::response_parser<bhttp::string_body> parser;
  parser.body_limit(64 * 1024);
  auto [ec, n] = co_await bhttp::async_read(stream, buffer, parser, asio::as_tuple(use_awaitable));
  (void)n;
  if (ec && ec != bhttp::error::body_limit) throw beast::system_error(ec);
  co_return int(parser.get().result_int());
}

asio::awaitable<int> attempt(WebhookUrl url, bhttp::request<bhttp::string_body> req) {
  auto ex = co_await asio::this_coro::executor;
  asio::ip::tcp::resolver resolver(ex);
  const auto addresses = co_await resolver.async_resolve(url.host, url.port, use_awaitable);
  if (!url.https) {
    beast::tcp_stream stream(ex);
    co_await stream.async_connect(addresses, use_awaitable);
    co_return co_await exchange(stream, req);
  }
  asio::ssl::context ctx(asio::ssl::context::tls_client);
  ctx.set_default_verify_paths();
  ctx.set_verify_mode(asio::ssl::verify_peer);
  beast::ssl_stream<beast::tcp_stream> stream(ex, ctx);
  if (!SSL_set_tlsext_host_name(stream.native_handle(), url.host.c_str()))
    throw std::runtime_error("cannot set the TLS server name " + url.host);
  stream.set_verify_callback(asio::ssl::host_name_verification(url.host));
  co_await beast::get_lowest_layer(stream).async_connect(addresses, use_awaitable);
  co_await stream.async_handshake(asio::ssl::stream_base::client, use_awaitable);
  co_return co_await exchange(stream, req);
}

}  // namespace

void PostStopper::stop() {
  std::lock_guard lock(mu_);
  stopped_ = true;
  for (asio::io_context* ioc : running_) ioc->stop();
}

bool PostStopper::enter(asio::io_context* ioc) {
  std::lock_guard lock(mu_);
  if (stopped_) return false;
  running_.insert(ioc);
  return true;
}

bool PostStopper::leave(asio::io_context* ioc) {
  std::lock_guard lock(mu_);
  running_.erase(ioc);
  return stopped_;
}

PostAnswer post_webhook(const WebhookUrl& url, const std::string& body,
                        const std::vector<std::pair<std::string, std::string>>& headers,
                        std::chrono::milliseconds timeout, PostStopper* stopper) {
  PostAnswer out;
  asio::io_context ioc;
  bool finished = false;
  asio::co_spawn(ioc, attempt(url, make_request(url, body, headers)), [&](std::exception_ptr e, int status) {
    finished = true;
    if (!e) {
      out.status = status;
      return;
    }
    try {
      std::rethrow_exception(e);
    } catch (const std::exception& x) {
      out.error = x.what();
    }
  });
  if (stopper && !stopper->enter(&ioc)) return {std::nullopt, "stopped"};
  ioc.run_for(timeout);  // returns at the end, the timeout, or stop()
  const bool stopped = stopper && stopper->leave(&ioc);
  if (!finished) out.error = stopped ? "stopped" : "no answer within " + std::to_string(timeout.count()) + " ms";
  return out;
}

}  // namespace tessera::server
