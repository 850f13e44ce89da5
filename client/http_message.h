// The Beast messages of the client's requests and answers: one definition of what a request to the farm carries (the
// target under the URL's base path, Host, User-Agent, Content-Type, the request's fields, the bearer token,
// keep-alive) and of how an answer's header becomes an HttpResponse. HttpClient sends with them, and so does any
// asynchronous sender that must put the same bytes on the wire (bench/sim_workers).
#pragma once

#include "client/http_client.h"

#include <boost/beast/http/message.hpp>
#include <boost/beast/http/string_body.hpp>
#include <boost/beast/http/verb.hpp>
#include <boost/system/error_code.hpp>

#include <chrono>
#include <string>

namespace tessera::client {

/// The header of `request` (method `verb`) to `url`: HTTP/1.1, the target under the URL's base path, Host,
/// User-Agent, Content-Type when the request has one, the request's own fields, "Authorization: Bearer <token>" when
/// token is not empty, keep-alive. request.body is not used: the caller adds the body and calls prepare_payload().
boost::beast::http::request_header<> request_header(const HttpUrl& url, const std::string& token,
                                                    const HttpRequest& request, boost::beast::http::verb verb);

/// The whole request as HttpClient sends it: request_header() with request.body and its Content-Length.
boost::beast::http::request<boost::beast::http::string_body> beast_request(const HttpUrl& url, const std::string& token,
                                                                          const HttpRequest& request,
                                                                          boost::beast::http::verb verb);

/// Status and header fields (names lowercased) of a received answer's header; the body is the caller's to add.
HttpResponse response_head(const boost::beast::http::response_header<>& head);

/// A transport error's cause in words: "timed out after <limit> ms" for a timeout, else the error's message.
std::string describe_error(const boost::system::error_code& ec, std::chrono::milliseconds limit);

/// Whether a request of method `verb` may be sent again when its answer was lost: a lost answer may hide a request that
/// was carried out, and only these methods mean the same when carried out twice.
bool is_idempotent(boost::beast::http::verb verb);

/// Whether an error on a kept-alive connection means the server had closed it before a request reached it (end of
/// stream, reset, broken pipe, aborted, a TLS stream cut short).
bool is_stale_connection(const boost::system::error_code& ec);

}  // namespace tessera::client
