// One simulated worker's keep-alive HTTP connection to the coordinator, driven by an event loop (a C++20 coroutine on
// Boost.Asio) instead of a thread: the requests of client::HttpClient::send (the same header fields and bodies, from
// client/http_message.h), its timeouts and its handling of a kept-alive connection the server has closed.
#pragma once

#include "client/http_client.h"

#include <boost/asio/awaitable.hpp>
#include <boost/asio/ip/tcp.hpp>
#include <boost/beast/core/flat_buffer.hpp>
#include <boost/beast/core/tcp_stream.hpp>

#include <string>
#include <string_view>

namespace tessera::bench {

/// A plain-HTTP keep-alive connection to one server, opened on the first request and reopened when the server closed
/// it. Not thread-safe: use it from the coroutines of one event loop, one request at a time.
class AsyncConnection {
 public:
  /// A connection to url (plain http://), whose host resolved to endpoints, on executor; no connection is opened yet.
  AsyncConnection(boost::asio::any_io_executor executor, client::HttpUrl url,
                  boost::asio::ip::tcp::resolver::results_type endpoints, client::HttpTimeouts timeouts = {});
  /// Sends "Authorization: Bearer <token>" with every request from now on ("" sends none).
  void set_bearer_token(std::string token) { token_ = std::move(token); }
  /// Sends request with `body` in place of request.body (not copied: it must outlive the call) and reads the whole
  /// answer, as HttpClient::send does: throws client::TransportError (naming method, URL and cause) on transport
  /// failures and timeouts; a request that could not be written on a reused connection goes once more on a fresh
  /// one, and so does a GET, HEAD, PUT, DELETE or OPTIONS whose answer did not start.
  boost::asio::awaitable<client::HttpResponse> send(const client::HttpRequest& request, std::string_view body);
  /// send(request, request.body).
  boost::asio::awaitable<client::HttpResponse> send(const client::HttpRequest& request) {
    return send(request, request.body);
  }

 private:
  boost::asio::awaitable<void> connect(const std::string& what);  // opens the connection unless open
  bool peer_closed();                                             // the idle connection is readable: closed
  void close();

  client::HttpUrl url_;
  boost::asio::ip::tcp::resolver::results_type endpoints_;
  client::HttpTimeouts timeouts_;
  std::string token_;
  boost::beast::tcp_stream stream_;
  boost::beast::flat_buffer buffer_;
  bool open_ = false;
};

}  // namespace tessera::bench
