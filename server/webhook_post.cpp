#include "server/webhook_post.h"

#include <boost/asio/connect.hpp>
#include <boost/asio/ip/tcp.hpp>
#include <boost/asio/ssl.hpp>
#include <boost/beast/core.hpp>
#include <boost/beast/http.hpp>
#include <boost/beast/ssl.hpp>
#include <boost/beast/version.hpp>

#include <openssl/ssl.h>

namespace tessera::server {

namespace {

namespace asio = boost::asio;
namespace beast = boost::beast;
namespace bhttp = beast::http;

template <class Stream>
int exchange(Stream& stream, const WebhookUrl& url, const std::string& body,
             const std::vector<std::pair<std::string, std::string>>& headers) {
  bhttp::request<bhttp::string_body> req{bhttp::verb::post, url.target, 11};
  req.set(bhttp::field::host, url.host);
  req.set(bhttp::field::user_agent, "tessera-webhook");
  req.set(bhttp::field::content_type, "application/json");
  for (const auto& [name, value] : headers) req.set(name, value);
  req.body() = body;
  req.prepare_payload();
  bhttp::write(stream, req);
  beast::flat_buffer buffer;
  bhttp::response_parser<bhttp::string_body> parser;
  parser.body_limit(64 * 1024);  // the answer's body is not used; a large one is cut off, not read
  beast::error_code ec;
  bhttp::read(stream, buffer, parser, ec);
  if (ec && ec != bhttp::error::body_limit) throw beast::system_error(ec);
  return int(parser.get().result_int());
}

}  // namespace

PostAnswer post_webhook(const WebhookUrl& url, const std::string& body,
                        const std::vector<std::pair<std::string, std::string>>& headers,
                        std::chrono::milliseconds timeout) {
  PostAnswer out;
  try {
    asio::io_context ioc;
    asio::ip::tcp::resolver resolver(ioc);
    const auto addresses = resolver.resolve(url.host, url.port);
    if (!url.https) {
      beast::tcp_stream stream(ioc);
      stream.expires_after(timeout);
      stream.connect(addresses);
      out.status = exchange(stream, url, body, headers);
      beast::error_code ignored;
      stream.socket().shutdown(asio::ip::tcp::socket::shutdown_both, ignored);
      return out;
    }
    asio::ssl::context ctx(asio::ssl::context::tls_client);
    ctx.set_default_verify_paths();
    ctx.set_verify_mode(asio::ssl::verify_peer);
    beast::ssl_stream<beast::tcp_stream> stream(ioc, ctx);
    if (!SSL_set_tlsext_host_name(stream.native_handle(), url.host.c_str()))
      throw beast::system_error(beast::error_code(int(::ERR_get_error()), asio::error::get_ssl_category()));
    stream.set_verify_callback(asio::ssl::host_name_verification(url.host));
    beast::get_lowest_layer(stream).expires_after(timeout);
    beast::get_lowest_layer(stream).connect(addresses);
    stream.handshake(asio::ssl::stream_base::client);
    out.status = exchange(stream, url, body, headers);
  } catch (const std::exception& e) {
    if (!out.status) out.error = e.what();
  }
  return out;
}

}  // namespace tessera::server
