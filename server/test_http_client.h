// Test helper: a synchronous HTTP/1.1 client over Beast that can reuse its connection (server tests only).
#pragma once

#include <boost/asio/ip/tcp.hpp>
#include <boost/beast/core.hpp>
#include <boost/beast/http.hpp>
#include <nlohmann/json.hpp>

#include <optional>
#include <string>
#include <utility>
#include <vector>

namespace tessera::server::testing {

/// One response as the client saw it.
struct Reply {
  unsigned status = 0;                                      ///< Status code.
  std::string body;                                         ///< Body bytes.
  boost::beast::http::response<boost::beast::http::string_body> msg;  ///< The whole message (headers).
  /// The body parsed as JSON.
  nlohmann::json js() const { return nlohmann::json::parse(body); }
};

/// A client for one endpoint; not thread-safe.
class Client {
 public:
  /// A client for ep; connects on the first request.
  explicit Client(boost::asio::ip::tcp::endpoint ep) : ep_(ep) {}
  /// Sends a request with optional extra headers and reads the whole response.
  Reply send(boost::beast::http::verb method, const std::string& target, std::string body = {},
             std::vector<std::pair<std::string, std::string>> headers = {}) {
    namespace http = boost::beast::http;
    if (!stream_) {
      stream_.emplace(ioc_);
      stream_->connect(ep_);
    }
    http::request<http::string_body> req{method, target, 11};
    req.set(http::field::host, "127.0.0.1");
    for (auto& [k, v] : headers) req.set(k, v);
    req.body() = std::move(body);
    req.prepare_payload();
    http::write(*stream_, req);
    boost::beast::flat_buffer buf;
    http::response_parser<http::string_body> parser;
    parser.body_limit(1u << 30);
    if (method == http::verb::head) parser.skip(true);
    http::read(*stream_, buf, parser);
    Reply r;
    r.msg = parser.release();
    r.status = r.msg.result_int();
    r.body = r.msg.body();
    if (!r.msg.keep_alive()) close();
    return r;
  }
  /// Closes the connection.
  void close() {
    if (!stream_) return;
    boost::beast::error_code ec;
    stream_->socket().shutdown(boost::asio::ip::tcp::socket::shutdown_both, ec);
    stream_.reset();
  }

 private:
  boost::asio::io_context ioc_;
  boost::asio::ip::tcp::endpoint ep_;
  std::optional<boost::beast::tcp_stream> stream_;
};

}  // namespace tessera::server::testing
