#include "client/http_message.h"

#include <boost/asio/error.hpp>
#include <boost/asio/ssl/error.hpp>
#include <boost/beast/core/error.hpp>
#include <boost/beast/http/error.hpp>

#include <algorithm>
#include <cctype>

namespace tessera::client {

namespace asio = boost::asio;
namespace http = boost::beast::http;

http::request_header<> request_header(const HttpUrl& url, const std::string& token, const HttpRequest& request,
                                      http::verb verb) {
  http::request_header<> h;
  h.method(verb);
  h.target(url.base_path + request.target);
  h.version(11);
  h.set(http::field::host, url.host + ":" + url.port);
  h.set(http::field::user_agent, "tessera/" TESSERA_VERSION);
  if (!request.content_type.empty()) h.set(http::field::content_type, request.content_type);
  for (const auto& [k, v] : request.headers) h.set(k, v);
  if (!token.empty()) h.set(http::field::authorization, "Bearer " + token);
  return h;
}

http::request<http::string_body> beast_request(const HttpUrl& url, const std::string& token, const HttpRequest& request,
                                               http::verb verb) {
  http::request<http::string_body> req{request_header(url, token, request, verb)};
  req.body() = request.body;
  req.keep_alive(true);
  req.prepare_payload();
  return req;
}

HttpResponse response_head(const http::response_header<>& head) {
  HttpResponse out;
  out.status = int(head.result_int());
  for (const auto& field : head) {
    std::string name(field.name_string());
    std::transform(name.begin(), name.end(), name.begin(), [](unsigned char c) { return char(std::tolower(c)); });
    out.headers[name] = std::string(field.value());
  }
  return out;
}

std::string describe_error(const boost::system::error_code& ec, std::chrono::milliseconds limit) {
  if (ec == boost::beast::error::timeout) return "timed out after " + std::to_string(limit.count()) + " ms";
  return ec.message();
}

bool is_stale_connection(const boost::system::error_code& ec) {
  return ec == http::error::end_of_stream || ec == asio::error::eof || ec == asio::error::connection_reset ||
         ec == asio::error::broken_pipe || ec == asio::error::connection_aborted ||
         ec == asio::ssl::error::stream_truncated;
}

bool is_idempotent(http::verb verb) {
  return verb == http::verb::get || verb == http::verb::head || verb == http::verb::put ||
         verb == http::verb::delete_ || verb == http::verb::options;
}

}  // namespace tessera::client
