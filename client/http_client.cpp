#include "client/http_client.h"

#include "client/http_message.h"
#include "net/byte_stream.h"
#include "protocol/messages.h"

#include <boost/asio/connect.hpp>
#include <boost/asio/io_context.hpp>
#include <boost/asio/ip/tcp.hpp>
#include <boost/beast/core/error.hpp>
#include <boost/beast/core/flat_buffer.hpp>
#include <boost/beast/http/empty_body.hpp>
#include <boost/beast/http/parser.hpp>
#include <boost/beast/http/buffer_body.hpp>
#include <boost/beast/http/read.hpp>
#include <boost/beast/http/string_body.hpp>
#include <boost/beast/http/write.hpp>
#include <nlohmann/json.hpp>
#include <openssl/ssl.h>
#include <openssl/x509_vfy.h>
#include <poll.h>

#include <algorithm>
#include <array>
#include <cctype>
#include <charconv>
#include <optional>

namespace tessera::client {

namespace asio = boost::asio;
namespace beast = boost::beast;
namespace http = boost::beast::http;
namespace ssl = boost::asio::ssl;
using tcp = asio::ip::tcp;
using boost::system::error_code;

std::string HttpUrl::to_string() const { return (tls ? "https://" : "http://") + host + ":" + port + base_path; }

HttpUrl parse_http_url(std::string_view url) {
  const std::string original(url);
  HttpUrl out;
  if (url.starts_with("https://")) {
    url.remove_prefix(8);
    out.tls = true;
    out.port = "443";
  } else if (url.starts_with("http://")) {
    url.remove_prefix(7);
  } else if (url.find("://") != std::string_view::npos) {
    throw std::invalid_argument("'" + original + "': only http:// and https:// URLs are supported");
  }
  const size_t slash = url.find('/');
  std::string_view authority = url.substr(0, slash);
  if (slash != std::string_view::npos) {
    std::string_view path = url.substr(slash);
    while (!path.empty() && path.back() == '/') path.remove_suffix(1);
    out.base_path = std::string(path);
  }
  std::string_view host = authority;
  if (!authority.empty() && authority.front() == '[') {  // [v6]:port
    const size_t close = authority.find(']');
    if (close == std::string_view::npos) throw std::invalid_argument("'" + original + "': unterminated IPv6 address");
    host = authority.substr(1, close - 1);
    authority.remove_prefix(close + 1);
    if (!authority.empty() && authority.front() != ':')
      throw std::invalid_argument("'" + original + "': unexpected text after the IPv6 address");
    if (!authority.empty()) out.port = std::string(authority.substr(1));
  } else if (const size_t colon = authority.rfind(':'); colon != std::string_view::npos) {
    host = authority.substr(0, colon);
    out.port = std::string(authority.substr(colon + 1));
  }
  if (host.empty()) throw std::invalid_argument("'" + original + "': no host");
  out.host = std::string(host);
  int port = 0;
  const auto [end, ec] = std::from_chars(out.port.data(), out.port.data() + out.port.size(), port);
  if (out.port.empty() || ec != std::errc() || end != out.port.data() + out.port.size() || port < 1 || port > 65535)
    throw std::invalid_argument("'" + original + "': bad port '" + out.port + "'");
  return out;
}

std::string HttpResponse::header(std::string_view name) const {
  std::string key(name);
  std::transform(key.begin(), key.end(), key.begin(), [](unsigned char c) { return char(std::tolower(c)); });
  const auto it = headers.find(key);
  return it == headers.end() ? std::string() : it->second;
}

std::string HttpResponse::error_text() const {
  try {
    return protocol::parse_answer<protocol::ErrorAnswer>(body, "error answer").error;
  } catch (const protocol::ProtocolError&) {  // not a JSON refusal: the body itself
  }
  std::string text = body.size() > 300 ? body.substr(0, 300) + "..." : body;
  std::replace_if(text.begin(), text.end(), [](unsigned char c) { return c < 0x20; }, ' ');
  while (!text.empty() && text.back() == ' ') text.pop_back();
  return text.empty() ? "HTTP " + std::to_string(status) : text;
}

struct HttpClient::Impl {
  // Room for full reads (net::kHttpReadBytes): a result download would otherwise arrive 512 bytes a system call.
  Impl() { buffer.reserve(net::kHttpReadBytes); }

  asio::io_context ioc;
  std::shared_ptr<ssl::context> tls_context;  // set for https:// URLs
  std::unique_ptr<net::ByteStream> stream;    // the open connection
  beast::flat_buffer buffer;
  bool connected = false;
  const std::function<bool()>* interrupted = nullptr;  // asked by run() every 100 ms while set (send's caller's)
  bool was_interrupted = false;                         // run() gave up on an operation because of it
  HttpTimeouts timeouts;
  uint64_t max_response_bytes = 0;

  beast::tcp_stream& lowest() { return stream->lowest(); }
  bool is_tls() const { return tls_context != nullptr; }

  // The completion handler of every operation: keeps the error (one type, so each operation is compiled once).
  struct KeepError {
    error_code* result;
    template <class... Rest>
    void operator()(error_code ec, Rest&&...) const {
      *result = ec;
    }
  };

  // Starts one asynchronous operation with `start(handler)` and runs the context until it completes; the stream's
  // expiry (set by the caller) turns a stalled operation into beast::error::timeout.
  template <class Start>
  error_code run(Start&& start) {
    error_code result = asio::error::would_block;
    ioc.restart();
    start(KeepError{&result});
    if (!interrupted || !*interrupted) {
      ioc.run();
      return result;
    }
    while (!ioc.stopped()) {
      ioc.run_for(std::chrono::milliseconds(100));
      if (!ioc.stopped() && (*interrupted)()) {
        was_interrupted = true;
        lowest().cancel();
        ioc.run();
      }
    }
    return result;
  }

  // run() for an operation on the open stream: op(stream, handler).
  template <class Op>
  error_code run_on_stream(Op&& op) {
    return run([&](KeepError handler) { op(*stream, handler); });
  }

  // A fresh stream for a new connection, set up to check that the certificate names `host`.
  void open_stream(const std::string& host) {
    buffer.clear();
    if (!tls_context) {
      stream = net::ByteStream::plain(ioc.get_executor());
      return;
    }
    stream = net::ByteStream::tls(ioc.get_executor(), *tls_context);
    SSL* native = stream->tls_handle();
    error_code ec;
    asio::ip::make_address(host, ec);
    if (!ec) {
      X509_VERIFY_PARAM_set1_ip_asc(SSL_get0_param(native), host.c_str());  // an address must be an IP SAN
    } else {
      SSL_set_tlsext_host_name(native, host.c_str());  // SNI
      SSL_set1_host(native, host.c_str());             // a DNS SAN (wildcards allowed)
    }
  }

  // Why a handshake failed, in words a user can act on.
  std::string handshake_failure(const error_code& ec) {
    if (ec == beast::error::timeout) return "timed out after " + std::to_string(timeouts.connect.count()) + " ms";
    const long verify = stream && stream->tls_handle() ? SSL_get_verify_result(stream->tls_handle()) : X509_V_OK;
    if (verify != X509_V_OK)
      return std::string("the server's certificate is not accepted: ") + X509_verify_cert_error_string(verify) +
             " (trust its CA with --ca-file; the certificate must name the host or IP address of the URL)";
    return with_hint(ec);
  }

  // The error's text, with what to do about the TLS failures a user can fix. With TLS 1.3 a refused client
  // certificate shows only when the first response is read, so reads and writes use this too.
  std::string with_hint(const error_code& ec) const {
    const std::string reason = ec.message();
    if (!is_tls() || ec.category() != asio::error::get_ssl_category()) return reason;
    if (reason.find("wrong version number") != std::string::npos || reason.find("packet length too long") != std::string::npos)
      return reason + " (does the server speak plain HTTP? then use an http:// URL)";
    if (reason.find("certificate required") != std::string::npos || reason.find("unknown ca") != std::string::npos ||
        reason.find("bad certificate") != std::string::npos || reason.find("handshake failure") != std::string::npos)
      return reason + " (the server requires a client certificate from a CA it trusts: --tls-cert, --tls-key)";
    return reason;
  }

  // Whether the server has closed (or written to) the idle kept-alive connection: readable before any request was
  // sent means an end of stream, a TLS close_notify or bytes nobody asked for; either way it cannot carry a request.
  bool peer_closed() {
    pollfd p{};
    p.fd = lowest().socket().native_handle();
    p.events = POLLIN;
    return ::poll(&p, 1, 0) != 0;
  }

  void close() {
    error_code ignored;
    if (stream) {
      lowest().socket().shutdown(tcp::socket::shutdown_both, ignored);
      lowest().close();
    }
    stream.reset();
    buffer.clear();
    connected = false;
  }
};

HttpClient::HttpClient(HttpUrl url, HttpTimeouts timeouts, uint64_t max_response_bytes, const ClientTlsFiles& tls)
    : url_(std::move(url)), impl_(std::make_unique<Impl>()) {
  impl_->timeouts = timeouts;
  impl_->max_response_bytes = max_response_bytes;
  if (!url_.tls && tls.any())
    throw std::invalid_argument("TLS files are given but " + url_.to_string() + " is plain HTTP: use an https:// URL");
  if (url_.tls) {
    try {
      impl_->tls_context = make_client_tls_context(tls);
    } catch (const std::runtime_error& e) {
      throw std::invalid_argument(e.what());
    }
  }
}

HttpClient::HttpClient(HttpUrl url, std::unique_ptr<Impl> impl, std::string token)
    : url_(std::move(url)), token_(std::move(token)), impl_(std::move(impl)) {}

HttpClient::~HttpClient() { impl_->close(); }

std::unique_ptr<HttpClient> HttpClient::another() const {
  auto im = std::make_unique<Impl>();
  im->tls_context = impl_->tls_context;
  im->timeouts = impl_->timeouts;
  im->max_response_bytes = impl_->max_response_bytes;
  return std::unique_ptr<HttpClient>(new HttpClient(url_, std::move(im), token_));
}

void HttpClient::connect(const std::string& what) {
  Impl& im = *impl_;
  if (im.connected) return;
  error_code ec;
  tcp::resolver resolver(im.ioc);
  const auto endpoints = resolver.resolve(url_.host, url_.port, ec);
  if (ec) throw TransportError(what + ": cannot resolve " + url_.host + ": " + ec.message());
  im.open_stream(url_.host);
  im.lowest().expires_after(im.timeouts.connect);
  ec = im.run([&](auto handler) { im.lowest().async_connect(endpoints, std::move(handler)); });
  if (ec) {
    im.close();
    throw TransportError(what + ": cannot connect: " + describe_error(ec, im.timeouts.connect));
  }
  // Requests are small writes answered at once: without TCP_NODELAY, Nagle's algorithm holds a request's last
  // segment until the server's delayed ACK (tens of milliseconds per request on loopback).
  im.lowest().socket().set_option(tcp::no_delay(true), ec);
  if (im.is_tls()) {
    im.lowest().expires_after(im.timeouts.connect);
    ec = im.run([&](auto handler) { im.stream->async_handshake(ssl::stream_base::client, handler); });
    if (ec) {
      const std::string why = im.handshake_failure(ec);
      im.close();
      throw TransportError(what + ": TLS handshake failed: " + why);
    }
  }
  im.connected = true;
}

void HttpClient::close() { impl_->close(); }

HttpRequest make_request(std::string method, std::string target, std::string body, std::string content_type) {
  HttpRequest r;
  r.method = std::move(method);
  r.target = std::move(target);
  r.body = std::move(body);
  if (!r.body.empty()) r.content_type = std::move(content_type);
  return r;
}

HttpResponse HttpClient::send(std::string method, std::string target, std::string body, std::string content_type) {
  return send(make_request(std::move(method), std::move(target), std::move(body), std::move(content_type)));
}

HttpResponse HttpClient::send(const HttpRequest& request, const std::function<bool()>& interrupted) {
  Impl& im = *impl_;
  struct Asking {
    Impl& im;
    ~Asking() { im.interrupted = nullptr; }
  } asking{im};
  im.interrupted = &interrupted;
  im.was_interrupted = false;
  try {
    return send(request);
  } catch (const TransportError&) {
    if (!im.was_interrupted) throw;
    im.close();
    throw RequestInterrupted(request.method + " " + url_.to_string() + request.target + ": given up while under way");
  }
}

HttpResponse HttpClient::send(const HttpRequest& request) {
  Impl& im = *impl_;
  const std::string what = request.method + " " + url_.to_string() + request.target;
  const http::verb verb = http::string_to_verb(request.method);
  if (verb == http::verb::unknown) throw TransportError(what + ": unknown method");

  const http::request<http::string_body> req = beast_request(url_, token_, request, verb);
  const bool idempotent = is_idempotent(verb);  // may go again without the caller knowing

  for (int attempt = 0;; ++attempt) {
    if (im.connected && im.peer_closed()) im.close();
    const bool reused = im.connected;
    connect(what);

    im.lowest().expires_after(im.timeouts.write);
    error_code ec = im.run_on_stream([&](auto& stream, auto handler) { http::async_write(stream, req, handler); });
    if (ec) {
      const std::string why = ec == beast::error::timeout ? describe_error(ec, im.timeouts.write) : im.with_hint(ec);
      im.close();
      if (reused && attempt == 0 && ec != beast::error::timeout) continue;
      throw TransportError(what + ": cannot send the request: " + why);
    }

    http::response_parser<http::string_body> parser;
    parser.body_limit(im.max_response_bytes);
    if (verb == http::verb::head) parser.skip(true);
    im.lowest().expires_after(im.timeouts.read);
    ec = im.run_on_stream([&](auto& stream, auto handler) { http::async_read(stream, im.buffer, parser, std::move(handler)); });
    if (ec) {
      const bool got_some = parser.got_some();
      const std::string why = ec == beast::error::timeout ? describe_error(ec, im.timeouts.read) : im.with_hint(ec);
      im.close();
      if (reused && attempt == 0 && !got_some && is_stale_connection(ec)) {
        if (idempotent) continue;
        throw TransportError(what + ": the server closed the connection without an answer (" + why +
                             "); the request may or may not have been carried out");
      }
      if (ec == http::error::body_limit)
        throw TransportError(what + ": response body larger than " + std::to_string(im.max_response_bytes) + " bytes");
      throw TransportError(what + ": cannot read the response: " + why);
    }
    im.lowest().expires_never();

    auto res = parser.release();
    HttpResponse out = response_head(res);
    out.body = std::move(res.body());
    if (!res.keep_alive()) im.close();
    return out;
  }
}

HttpResponse HttpClient::stream(const HttpRequest& request, std::chrono::milliseconds idle,
                                const std::function<bool(std::string_view)>& on_data, const std::function<bool()>& stop) {
  Impl& im = *impl_;
  const std::string what = request.method + " " + url_.to_string() + request.target;
  const http::verb verb = http::string_to_verb(request.method);
  if (verb == http::verb::unknown) throw TransportError(what + ": unknown method");
  http::request<http::string_body> writable = beast_request(url_, token_, request, verb);
  writable.keep_alive(false);
  const http::request<http::string_body>& req = writable;  // const, as send() writes it: one write operation for both
  im.close();  // a connection of its own
  struct Closer {
    Impl& im;
    ~Closer() { im.close(); }
  } closer{im};
  connect(what);
  im.lowest().expires_after(im.timeouts.write);
  error_code ec = im.run_on_stream([&](auto& stream, auto handler) { http::async_write(stream, req, handler); });
  if (ec) throw TransportError(what + ": cannot send the request: " + (ec == beast::error::timeout ? describe_error(ec, im.timeouts.write) : im.with_hint(ec)));

  http::response_parser<http::buffer_body> parser;
  parser.body_limit(boost::none);
  im.lowest().expires_after(im.timeouts.read);
  ec = im.run_on_stream([&](auto& stream, auto handler) { http::async_read_header(stream, im.buffer, parser, std::move(handler)); });
  if (ec) throw TransportError(what + ": cannot read the response: " + (ec == beast::error::timeout ? describe_error(ec, im.timeouts.read) : im.with_hint(ec)));
  HttpResponse out = response_head(parser.get());
  const bool streaming = out.status == 200;
  if (streaming && !on_data({})) return out;
  std::array<char, 8192> buf;
  while (!parser.is_done()) {
    parser.get().body().data = buf.data();
    parser.get().body().size = buf.size();
    im.lowest().expires_after(streaming ? idle : im.timeouts.read);
    // As im.run_on_stream(), but asking `stop` every 100 ms while the read waits.
    bool done = false;
    ec = asio::error::would_block;
    im.ioc.restart();
    const auto on_read = [&](error_code e, std::size_t) {
      ec = e;
      done = true;
    };
    http::async_read_some(*im.stream, im.buffer, parser, on_read);
    while (!done) {
      im.ioc.run_for(std::chrono::milliseconds(100));
      if (!done && stop && stop()) {
        im.lowest().cancel();
        im.ioc.run();
        return out;
      }
    }
    if (ec == http::error::need_buffer) ec = {};
    if (ec) {
      const std::chrono::milliseconds limit = streaming ? idle : im.timeouts.read;
      throw TransportError(what + ": the stream broke: " + (ec == beast::error::timeout ? describe_error(ec, limit) : im.with_hint(ec)));
    }
    const std::string_view got(buf.data(), buf.size() - parser.get().body().size);
    if (!streaming) {
      if (out.body.size() + got.size() > (std::size_t(1) << 20)) throw TransportError(what + ": refusal body too large");
      out.body.append(got);
    } else if (!got.empty() && !on_data(got)) {
      break;
    }
  }
  return out;
}

}  // namespace tessera::client
