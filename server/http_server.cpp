#include "server/http_server.h"

#include "server/log_limit.h"

#include "net/byte_stream.h"
#include "protocol/messages.h"

#include <boost/asio/dispatch.hpp>
#include <boost/asio/executor_work_guard.hpp>
#include <boost/asio/post.hpp>
#include <boost/asio/ssl/error.hpp>
#include <boost/asio/steady_timer.hpp>
#include <boost/asio/strand.hpp>
#include <boost/asio/write.hpp>
#include <boost/beast/core.hpp>
#include <openssl/err.h>
#include <openssl/ssl.h>
#include <spdlog/spdlog.h>

#include <arpa/inet.h>
#include <fcntl.h>
#include <netinet/in.h>
#include <sys/resource.h>
#include <sys/socket.h>

#include <algorithm>
#include <array>
#include <atomic>
#include <cerrno>
#include <cstring>
#include <limits>
#include <map>
#include <mutex>
#include <optional>

namespace tessera::server {

namespace asio = boost::asio;
namespace beast = boost::beast;
namespace ssl = asio::ssl;
using tcp = asio::ip::tcp;

HttpResponse json_error(http::status status, const std::string& text, unsigned version) {
  HttpResponse res{status, version};
  res.set(http::field::content_type, "application/json");
  // The text may quote a request target or key with arbitrary bytes: replace what is not UTF-8 instead of throwing.
  res.body() = protocol::error_text(protocol::ErrorAnswer{text});
  res.prepare_payload();
  return res;
}

class Session;

struct HttpServer::State {
  State(asio::io_context& i, asio::thread_pool& p, HttpHandler& h, HttpServerOptions o)
      : ioc(i), pool(p), handler(h), opt(std::move(o)), acceptor(asio::make_strand(i)) {
    // Any TLS file named builds the context, so a key or client CA without a certificate is an error, not plain HTTP.
    const TlsServerFiles& t = opt.tls;
    if (!t.cert_file.empty() || !t.key_file.empty() || !t.client_ca_file.empty()) tls_context = make_server_tls_context(t);
  }
  asio::io_context& ioc;
  asio::thread_pool& pool;
  HttpHandler& handler;
  HttpServerOptions opt;
  tcp::acceptor acceptor;
  std::atomic<bool> stopping{false};
  std::mutex mu;
  std::map<uint64_t, std::weak_ptr<Session>> sessions;
  uint64_t next_session = 1;
  std::shared_ptr<ssl::context> tls_context;  // guarded by mu; replaced by reload_tls(), null for plain HTTP
  // Failed accepts (out of descriptors, say) wait before the next try, 10 ms doubling to 1 s, back to none after an
  // accept that works; their log lines, and those of connections over the limit, are bounded.
  asio::steady_timer accept_pause{acceptor.get_executor()};
  std::chrono::milliseconds accept_backoff{0};
  LogLimit accept_log{10, std::chrono::minutes(1)};
  LogLimit over_limit_log{10, std::chrono::minutes(1)};
  LogLimit peer_log{10, std::chrono::minutes(1)};
  RefusalRate refusals{opt.peers.refusals_per_minute};
};

namespace {

// Reads and discards what the client still sends until an error (its close, or the expiry the caller set on `stream`),
// then closes the socket. `owner` (holding `stream` and `buf`) is kept alive until then.
void drain_and_close(beast::tcp_stream& stream, std::array<char, 4096>& buf, std::shared_ptr<void> owner) {
  stream.async_read_some(asio::buffer(buf), [&stream, &buf, owner = std::move(owner)](beast::error_code ec,
                                                                                       std::size_t) mutable {
    if (!ec) return drain_and_close(stream, buf, std::move(owner));
    beast::error_code ignored;
    stream.socket().close(ignored);
  });
}

// The last step of every close here: half-closes the connection (the client reads the end of the answer), then
// drains it as above, so that an unread request does not turn the close into a reset that destroys the answer in
// flight; a connection that cannot be half-closed is closed at once.
void half_close_and_drain(beast::tcp_stream& stream, std::array<char, 4096>& buf, std::shared_ptr<void> owner) {
  beast::error_code ec;
  stream.socket().shutdown(tcp::socket::shutdown_send, ec);
  if (ec) return void(stream.socket().close(ec));
  drain_and_close(stream, buf, std::move(owner));
}

// A connection refused in plain HTTP (over the connection limit, or a plain request on the TLS port): answered at once
// without reading its request, half-closed, and drained for at most a second so the answer is not lost to a reset.
class Refusal : public std::enable_shared_from_this<Refusal> {
 public:
  Refusal(tcp::socket&& socket, HttpResponse res)
      : stream_(net::ByteStream::plain(std::move(socket))), res_(std::move(res)) {
    res_.keep_alive(false);
  }

  void run() {
    stream_->lowest().expires_after(std::chrono::seconds(1));
    http::async_write(*stream_, res_, [self = shared_from_this()](beast::error_code ec, std::size_t) {
      beast::error_code ignored;
      if (ec) return void(self->stream_->lowest().socket().close(ignored));
      half_close_and_drain(self->stream_->lowest(), self->buf_, self);
    });
  }

 private:
  std::unique_ptr<net::ByteStream> stream_;
  HttpResponse res_;
  std::array<char, 4096> buf_;
};

}  // namespace

// The subject common name of the verified certificate the TLS peer presented, or "" (none, not verified, or plain TCP).
std::string verified_client_name(SSL* ssl) {
  if (!ssl) return "";
  X509* cert = SSL_get_peer_certificate(ssl);
  if (!cert) return "";
  std::string name;
  if (SSL_get_verify_result(ssl) == X509_V_OK) {
    char buf[256];
    const int n = X509_NAME_get_text_by_NID(X509_get_subject_name(cert), NID_commonName, buf, sizeof buf);
    if (n > 0) name.assign(buf, size_t(n));
  }
  X509_free(cert);
  return name;
}

// One connection: (with TLS, a server handshake first, within the read timeout,) then reads a request header, picks
// the body limit, reads the body, hands the request to the handler pool and writes the answer, all on the
// connection's strand; keep-alive loops back to the next header. One class for both: the stream hides whether the
// bytes go over TLS.
class Session : public std::enable_shared_from_this<Session> {
 public:
  Session(tcp::socket&& socket, asio::ip::address peer, std::shared_ptr<ssl::context> tls,
          std::shared_ptr<HttpServer::State> st, uint64_t id)
      : tls_(std::move(tls)), stream_(make_stream(std::move(socket), tls_.get())), st_(std::move(st)), id_(id),
        peer_(std::move(peer)), idle_timer_(stream_->get_executor()) {}

  ~Session() {
    std::lock_guard lock(st_->mu);
    st_->sessions.erase(id_);
  }

  // Starts the connection's work (handshake or first read) on its strand.
  void run() {
    asio::dispatch(stream_->get_executor(), [self = shared_from_this()] {
      if (self->tls_) self->handshake();
      else self->read_header();
    });
  }

  // Called at shutdown: a connection waiting for its next request is closed now; a busy one closes after answering; a
  // streamed body ends (its last chunk is written) and its connection closes.
  /// The remote address.
  const asio::ip::address& peer() const { return peer_; }
  /// True until a request of this connection carried an accepted credential.
  bool anonymous() const { return !trusted_; }

  /// Closes the connection if it is still anonymous and waiting for its request (it was displaced by a new one).
  void evict() {
    asio::dispatch(stream_->get_executor(), [self = shared_from_this()] {
      if (self->trusted_ || self->closing_ || !self->waiting_) return;
      beast::error_code ignored;
      self->lowest().socket().cancel(ignored);
    });
  }

  void stop_if_idle() {
    asio::dispatch(stream_->get_executor(), [self = shared_from_this()] {
      if (self->body_) {
        self->end_requested_ = true;
        return self->pump();
      }
      if (self->waiting_ && (!self->parser_ || !self->parser_->got_some())) self->lowest().cancel();
    });
  }

 private:
  static std::unique_ptr<net::ByteStream> make_stream(tcp::socket&& socket, ssl::context* tls) {
    if (tls) return net::ByteStream::tls(std::move(socket), *tls);
    return net::ByteStream::plain(std::move(socket));
  }

  beast::tcp_stream& lowest() { return stream_->lowest(); }

  void handshake() {
    waiting_ = true;
    lowest().expires_after(st_->opt.read_timeout);  // a stalled handshake is a stalled request
    stream_->async_handshake(ssl::stream_base::server, [self = shared_from_this()](beast::error_code ec) {
      self->waiting_ = false;
      if (ec) {
        spdlog::debug("connection {}: TLS handshake failed: {}", self->id_, ec.message());
        if (ec.category() == asio::error::get_ssl_category() && ERR_GET_REASON(ec.value()) == SSL_R_HTTP_REQUEST)
          return self->refuse_plain_http();
        beast::error_code ignored;
        self->lowest().socket().close(ignored);
        return;
      }
      self->cert_name_ = verified_client_name(self->stream_->tls_handle());
      self->read_header();
    });
  }

  // A plain HTTP request reached the TLS listener: answered 400 in plain HTTP on the bare socket, so the client learns
  // why; this connection ends here.
  void refuse_plain_http() {
    closing_ = true;
    std::make_shared<Refusal>(std::move(lowest().socket()),
                              json_error(http::status::bad_request, "this coordinator speaks HTTPS only: use an https:// URL"))
        ->run();
  }

  void read_header() {
    if (st_->stopping) return close();
    parser_.emplace();
    parser_->header_limit(std::uint32_t(st_->opt.header_limit));
    parser_->body_limit(std::numeric_limits<std::uint64_t>::max());
    // What the parser cannot consume piecewise (a header, a chunk's size line with its extensions, the trailer) must
    // fit the buffer, so the buffer's bound is what such a request can cost: a longer line is refused, not buffered.
    buffer_.max_size(st_->opt.header_limit + net::kHttpReadBytes);
    waiting_ = true;
    lowest().expires_after(st_->opt.read_timeout);  // covers the whole request, body included
    http::async_read_header(*stream_, buffer_, *parser_, beast::bind_front_handler(&Session::on_header, shared_from_this()));
  }

  void on_header(beast::error_code ec, std::size_t) {
    waiting_ = false;
    if (ec) return on_read_error(ec);
    auto& req = parser_->get();
    // Who the peer is, as the transport knows it; fields of these names a client sent are not believed.
    req.erase(kPeerAddressField);
    req.erase(kClientCertNameField);
    req.set(kPeerAddressField, peer_.to_string());
    if (!cert_name_.empty()) req.set(kClientCertNameField, cert_name_);
    if (!trusted_ && st_->handler.authenticated(req.base())) trusted_ = true;
    if (auto early = st_->handler.early_response(req.base())) {
      if (early->result() == http::status::unauthorized || early->result() == http::status::forbidden)
        st_->refusals.note(peer_, std::chrono::steady_clock::now());
      if (req.method() == http::verb::head) {
        const std::size_t n = early->body().size();
        early->body().clear();
        early->content_length(n);
      }
      return reply_and_close(std::move(*early));
    }
    const std::size_t limit = st_->handler.body_limit(req.base());
    parser_->body_limit(limit);
    if (const auto len = parser_->content_length(); len && *len > limit)
      return too_large(limit);
    // A chunked body's extensions count against the limit with its data (the parser counts only the data).
    chunk_budget_ = limit;
    parser_->on_chunk_header(count_chunk_);
    if (beast::iequals(req[http::field::expect], "100-continue")) {
      auto cont = std::make_shared<http::response<http::empty_body>>(http::status::continue_, req.version());
      http::async_write(*stream_, *cont, [self = shared_from_this(), cont](beast::error_code wec, std::size_t) {
        if (wec) return self->close();
        self->read_body();
      });
      return;
    }
    read_body();
  }

  void read_body() {
    // The header left buffer_ little free room (net::kHttpReadBytes): a tile upload or an asset gets up to a full read's
    // worth (a chunked body, of unknown length, a full read), given back in on_body().
    const auto len = parser_->content_length();
    const std::size_t room = len ? std::size_t(std::min<std::uint64_t>(*len, net::kHttpReadBytes))
                                 : parser_->chunked() ? net::kHttpReadBytes : 0;
    if (room > buffer_.capacity() - buffer_.size()) buffer_.reserve(buffer_.size() + room);
    http::async_read(*stream_, buffer_, *parser_, beast::bind_front_handler(&Session::on_body, shared_from_this()));
  }

  void on_read_error(beast::error_code ec) {
    if (ec == http::error::body_limit) return too_large(std::size_t(-1));
    if (ec == http::error::buffer_overflow) {
      // Only a header (whose own limit comes first), a chunk line or a trailer can fill the buffer.
      return reply_and_close(json_error(http::status::payload_too_large,
                                        "a chunk's size line or the trailer is longer than " +
                                            std::to_string(buffer_.max_size()) + " bytes"));
    }
    if (ec == http::error::end_of_stream || ec == beast::error::timeout || ec == asio::error::operation_aborted ||
        ec == asio::error::eof || ec == asio::error::connection_reset || ec.category() == asio::error::get_ssl_category() ||
        ec == ssl::error::stream_truncated) {
      if (ec == beast::error::timeout) spdlog::debug("connection {}: read timeout, closed", id_);
      return close();
    }
    if (ec == http::error::header_limit)
      return reply_and_close(json_error(http::status::request_header_fields_too_large,
                                        "request header is larger than the limit of " + std::to_string(st_->opt.header_limit) + " bytes"));
    reply_and_close(json_error(http::status::bad_request, "malformed HTTP request: " + ec.message()));
  }

  void too_large(std::size_t limit) {
    const std::string what = limit == std::size_t(-1) ? std::string("request body is larger than the limit")
                                                      : "request body is larger than the limit of " + std::to_string(limit) + " bytes";
    reply_and_close(json_error(http::status::payload_too_large, what));
  }

  void on_body(beast::error_code ec, std::size_t) {
    if (ec) return on_read_error(ec);
    buffer_.shrink_to_fit();  // an idle connection keeps no body-sized buffer
    lowest().expires_never();  // the handler may take a while; the write sets its own deadline
    HttpRequest req = parser_->release();
    const bool keep_alive = req.keep_alive();
    auto work = asio::make_work_guard(stream_->get_executor());  // keeps run() going while the pool works
    asio::post(st_->pool, [self = shared_from_this(), req = std::move(req), keep_alive, work = std::move(work)]() mutable {
      // The handler may answer later from another thread; the work guard travels with the reply.
      auto done = [self, keep_alive, work = std::make_shared<decltype(work)>(std::move(work))](HttpReply reply) {
        asio::post(self->stream_->get_executor(), [self, reply = std::move(reply), keep_alive, work]() mutable {
          if (reply.stream) return self->start_stream(std::move(reply.response), std::move(reply.stream));
          self->write(std::move(reply.response), keep_alive && !self->st_->stopping);
        });
      };
      self->st_->handler.handle_async(std::move(req), std::move(done));
    });
  }

  void reply_and_close(HttpResponse res) { write(std::move(res), false); }

  void write(HttpResponse res, bool keep_alive) {
    res.keep_alive(keep_alive);
    if (!res.has_content_length() && !res.chunked()) res.prepare_payload();
    auto sp = std::make_shared<HttpResponse>(std::move(res));
    lowest().expires_after(st_->opt.read_timeout);
    http::async_write(*stream_, *sp, [self = shared_from_this(), sp](beast::error_code ec, std::size_t) {
      if (ec) {
        spdlog::debug("connection {}: write failed: {}", self->id_, ec.message());
        return self->close();
      }
      if (!sp->keep_alive()) return self->close();
      self->read_header();
    });
  }

  // A streamed answer: the header at once, then the stream's chunks as they come (raw under a Content-Length the
  // handler set; otherwise chunked over HTTP/1.1, raw bytes ended by the close over HTTP/1.0), idle text after
  // stream_idle of quiet, and the connection's end when the stream ends. A read on the socket notices a client that closes its side (bytes it sends are ignored).
  void start_stream(HttpResponse head, std::shared_ptr<BodyStream> body) {
    body_ = std::move(body);
    // A body of known length (a file) keeps its Content-Length and goes out raw; one of unknown length is chunked
    // over HTTP/1.1 and ended by the close over HTTP/1.0.
    const bool sized = head.has_content_length();
    chunked_ = !sized && head.version() >= 11;
    head.keep_alive(false);
    head.body().clear();
    if (chunked_) head.chunked(true);
    else if (!sized) head.erase(http::field::content_length);
    auto header = std::make_shared<HttpResponse>(std::move(head));
    auto sr = std::make_shared<http::response_serializer<http::string_body>>(*header);
    writing_ = true;
    lowest().expires_after(st_->opt.read_timeout);
    http::async_write_header(*stream_, *sr, [self = shared_from_this(), header, sr](beast::error_code ec, std::size_t) {
      self->writing_ = false;
      self->lowest().expires_never();
      if (ec) return self->end_stream();
      self->watch_client();
      self->arm_idle();
      std::weak_ptr<Session> weak = self;
      self->body_->start([weak] {
        if (auto s = weak.lock()) asio::post(s->stream_->get_executor(), [s] { s->pump(); });
      });
      if (self->st_->stopping) self->end_requested_ = true;
      self->pump();
    });
  }

  // Writes what the stream has, unless a write is in flight (its completion pumps again).
  void pump() {
    if (!body_ || writing_ || stream_done_) return;
    BodyStream::Chunk c = body_->next();
    if (end_requested_) c.last = true;
    if (c.text.empty() && !c.last) return;
    write_chunk(std::move(c.text), c.last);
  }

  void write_chunk(std::string text, bool last) {
    out_.clear();
    if (chunked_ && !text.empty()) {
      static constexpr char kHex[] = "0123456789abcdef";
      std::string size;
      for (std::size_t n = text.size(); n > 0; n /= 16) size.insert(size.begin(), kHex[n % 16]);
      out_ = size + "\r\n" + text + "\r\n";
    } else if (!chunked_) {
      out_ = std::move(text);
    }
    if (chunked_ && last) out_ += "0\r\n\r\n";
    wrote_since_idle_ = true;
    if (out_.empty()) return end_stream();
    writing_ = true;
    lowest().expires_after(st_->opt.read_timeout);  // a client that stops reading is closed
    asio::async_write(*stream_, asio::buffer(out_), [self = shared_from_this(), last](beast::error_code ec, std::size_t) {
      self->writing_ = false;
      self->lowest().expires_never();
      if (ec) {
        spdlog::debug("connection {}: stream write failed: {}", self->id_, ec.message());
        return self->end_stream();
      }
      if (last) return self->end_stream();
      self->pump();
    });
  }

  void arm_idle() {
    idle_timer_.expires_after(st_->opt.stream_idle);
    idle_timer_.async_wait([self = shared_from_this()](beast::error_code ec) {
      if (ec || self->stream_done_) return;
      if (!self->wrote_since_idle_ && !self->writing_) {
        if (std::string idle = self->body_->idle_text(); !idle.empty()) self->write_chunk(std::move(idle), false);
      }
      self->wrote_since_idle_ = false;
      self->arm_idle();
    });
  }

  void watch_client() {
    watching_ = true;
    lowest().socket().async_read_some(asio::buffer(drain_), [self = shared_from_this()](beast::error_code ec, std::size_t) {
      self->watching_ = false;
      if (!ec && !self->stream_done_) return self->watch_client();
      if (!self->stream_done_) spdlog::debug("connection {}: the stream's client went away", self->id_);
      self->end_stream();
    });
  }

  // Ends the stream once: tells the body, stops the timer and the client watch, and closes when nothing is in flight.
  void end_stream() {
    if (!stream_done_) {
      stream_done_ = true;
      body_->stop();
      idle_timer_.cancel();
    }
    if (writing_ || watching_) {
      beast::error_code ignored;
      lowest().socket().cancel(ignored);  // their completions come back here
      return;
    }
    close();
  }

  // With TLS, first sends close_notify (for at most a second). Then half-closes, and reads and discards what the
  // client still sends (for at most a second) before closing, so an unread request body does not turn the close
  // into a reset that destroys the response in flight.
  void close() {
    if (closing_) return;
    closing_ = true;
    waiting_ = false;
    if (tls_) {
      lowest().expires_after(std::chrono::seconds(1));
      stream_->async_shutdown([self = shared_from_this()](beast::error_code) { self->finish_close(); });
    } else {
      finish_close();
    }
  }

  void finish_close() {
    lowest().expires_after(std::chrono::seconds(1));
    half_close_and_drain(lowest(), drain_, shared_from_this());
  }

  std::shared_ptr<ssl::context> tls_;  // the context this connection's handshake used (kept across a reload)
  std::unique_ptr<net::ByteStream> stream_;
  beast::flat_buffer buffer_;
  std::optional<http::request_parser<http::string_body>> parser_;
  std::uint64_t chunk_budget_ = 0;  // body bytes (data and chunk extensions) the request may still send
  std::function<void(std::uint64_t, beast::string_view, beast::error_code&)> count_chunk_ =
      [this](std::uint64_t size, beast::string_view extensions, beast::error_code& ec) {
        const std::uint64_t cost = size + extensions.size();
        if (cost > chunk_budget_) ec = http::error::body_limit;
        else chunk_budget_ -= cost;
      };
  std::shared_ptr<HttpServer::State> st_;
  uint64_t id_;
  asio::ip::address peer_;
  std::string cert_name_;  // the common name of the peer's verified client certificate, if it showed one
  std::atomic<bool> trusted_{false};  // written on the strand, read by the acceptor
  bool waiting_ = false;
  bool closing_ = false;
  std::array<char, 4096> drain_;
  // A streamed answer (start_stream).
  asio::steady_timer idle_timer_;
  std::shared_ptr<BodyStream> body_;
  std::string out_;               // the chunk being written
  bool chunked_ = false;
  bool writing_ = false;
  bool watching_ = false;         // the client watch's read is pending
  bool wrote_since_idle_ = false;
  bool end_requested_ = false;    // shutdown: the next write is the last
  bool stream_done_ = false;
};

namespace {

// Descriptors kept for what is not a connection: the database and its journal, blobs and results being read or
// written, the listening socket, the log.
constexpr rlim_t kReservedDescriptors = 64;

// --max-connections must fit the process's descriptor limit: the soft limit is raised towards the hard one when it is
// too low, and if that is not enough the connection limit is lowered to fit, saying so.
void fit_connections_to_descriptors(std::size_t& max_connections) {
  rlimit lim{};
  if (::getrlimit(RLIMIT_NOFILE, &lim) != 0) return;
  const rlim_t needed = rlim_t(max_connections) + kReservedDescriptors;
  if (lim.rlim_cur != RLIM_INFINITY && lim.rlim_cur < needed) {
    rlimit raised = lim;
    raised.rlim_cur = lim.rlim_max == RLIM_INFINITY ? needed : std::min(needed, lim.rlim_max);
    if (::setrlimit(RLIMIT_NOFILE, &raised) == 0) lim = raised;
  }
  if (lim.rlim_cur == RLIM_INFINITY || lim.rlim_cur >= needed) return;
  const std::size_t fits = lim.rlim_cur > kReservedDescriptors ? std::size_t(lim.rlim_cur - kReservedDescriptors) : 1;
  spdlog::warn("--max-connections {} does not fit the limit of {} open files (ulimit -n; {} kept for the database and "
               "files): serving at most {} connections",
               max_connections, uint64_t(lim.rlim_cur), uint64_t(kReservedDescriptors), fits);
  max_connections = fits;
}

// When every slot is taken: the oldest anonymous connection, waiting for its request, of the address that holds the
// most anonymous connections beyond its share, to be closed for the new one; null when no address holds more than its
// share. Needs st.mu.
std::shared_ptr<Session> displaceable(HttpServer::State& st) {
  const std::size_t share =
      st.opt.peers.anonymous_per_address > 0 ? st.opt.peers.anonymous_per_address : std::max<std::size_t>(1, st.opt.max_connections / 4);
  std::map<asio::ip::address, std::pair<std::size_t, std::shared_ptr<Session>>> held;  // count, oldest (lowest id)
  for (auto& [id, w] : st.sessions) {
    std::shared_ptr<Session> s = w.lock();
    if (!s || !s->anonymous()) continue;
    auto& [count, oldest] = held[s->peer()];
    ++count;
    if (!oldest) oldest = std::move(s);
  }
  std::shared_ptr<Session> pick;
  std::size_t most = share;
  for (auto& [address, entry] : held)
    if (entry.first > most) most = entry.first, pick = entry.second;
  return pick;
}

// Answers a connection at once, without reading its request (plain HTTP), or closes it (TLS: no handshake, which a
// flood of refused connections could make cost CPU).
void refuse(tcp::socket&& socket, bool tls, HttpResponse res) {
  if (tls) {
    beast::error_code ignored;
    socket.close(ignored);
    return;
  }
  std::make_shared<Refusal>(std::move(socket), std::move(res))->run();
}

void accept_next(const std::shared_ptr<HttpServer::State>& st) {
  st->acceptor.async_accept(asio::make_strand(st->ioc), [st](beast::error_code ec, tcp::socket socket) {
    if (ec == asio::error::operation_aborted || !st->acceptor.is_open() || st->stopping) return;
    if (ec) {
      st->accept_backoff = std::clamp(2 * st->accept_backoff, std::chrono::milliseconds(10), std::chrono::milliseconds(1000));
      uint64_t left_out = 0;
      if (st->accept_log.allow(left_out))
        spdlog::warn("accept failed: {}; next try in {} ms{}", ec.message(), st->accept_backoff.count(),
                     LogLimit::left_out_note(left_out, "failures"));
      st->accept_pause.expires_after(st->accept_backoff);
      st->accept_pause.async_wait([st](beast::error_code) { accept_next(st); });
      return;
    }
    st->accept_backoff = std::chrono::milliseconds(0);
    {
      // Responses are small writes a client waits for: no Nagle delay (see client/http_client.cpp).
      beast::error_code nodelay_ec;
      socket.set_option(tcp::no_delay(true), nodelay_ec);
      beast::error_code peer_ec;
      const asio::ip::address peer = socket.remote_endpoint(peer_ec).address();
      std::shared_ptr<Session> s, displaced;
      std::shared_ptr<ssl::context> tls;
      bool over_limit = false;
      const int blocked = st->refusals.blocked_for(peer, std::chrono::steady_clock::now());
      {
        std::lock_guard lock(st->mu);
        tls = st->tls_context;
        over_limit = st->sessions.size() >= st->opt.max_connections;
        if (over_limit && blocked == 0) {
          displaced = displaceable(*st);
          over_limit = !displaced;
        }
        if (!over_limit && blocked == 0) {
          const uint64_t id = st->next_session++;
          s = std::make_shared<Session>(std::move(socket), peer, tls, st, id);
          st->sessions.emplace(id, s);
        }
      }
      uint64_t left_out = 0;
      if (blocked > 0) {
        if (st->peer_log.allow(left_out))
          spdlog::warn("connection from {} refused: over --max-refusals-per-minute ({}){}", peer.to_string(),
                       st->opt.peers.refusals_per_minute, LogLimit::left_out_note(left_out, "refused connections"));
        HttpResponse res = json_error(http::status::too_many_requests,
                                      "too many refused credentials from " + peer.to_string() + "; retry in " +
                                          std::to_string(blocked) + " s");
        res.set(http::field::retry_after, std::to_string(blocked));
        refuse(std::move(socket), bool(tls), std::move(res));
      } else if (over_limit) {
        if (st->over_limit_log.allow(left_out))
          spdlog::warn("connection refused: {} connections open (--max-connections){}", st->opt.max_connections,
                       LogLimit::left_out_note(left_out, "refused connections"));
        HttpResponse res = json_error(http::status::service_unavailable, "too many connections (the limit is " +
                                                                        std::to_string(st->opt.max_connections) +
                                                                        "); retry later");
        res.set(http::field::retry_after, "1");
        refuse(std::move(socket), bool(tls), std::move(res));
      } else {
        if (displaced) {
          if (st->peer_log.allow(left_out))
            spdlog::warn("every connection slot taken: closing an idle connection of {}, which holds the most without "
                         "a credential{}",
                         displaced->peer().to_string(), LogLimit::left_out_note(left_out, "closed connections"));
          displaced->evict();
        }
        s->run();
      }
    }
    accept_next(st);
  });
}

}  // namespace

std::string listening_address(int fd) {
  const std::string what = "socket " + std::to_string(fd);
  int value = 0;
  socklen_t len = sizeof value;
  if (::getsockopt(fd, SOL_SOCKET, SO_TYPE, &value, &len) != 0)
    throw std::runtime_error(what + " is not an open socket: " + std::strerror(errno));
  if (value != SOCK_STREAM) throw std::runtime_error(what + " is not a TCP socket");
  len = sizeof value;
  if (::getsockopt(fd, SOL_SOCKET, SO_ACCEPTCONN, &value, &len) != 0 || value == 0)
    throw std::runtime_error(what + " is not listening");
  sockaddr_storage addr{};
  len = sizeof addr;
  if (::getsockname(fd, reinterpret_cast<sockaddr*>(&addr), &len) != 0)
    throw std::runtime_error(what + ": getsockname: " + std::strerror(errno));
  if (addr.ss_family == AF_INET) {
    const auto& in = reinterpret_cast<const sockaddr_in&>(addr);
    return asio::ip::address_v4(ntohl(in.sin_addr.s_addr)).to_string();
  }
  if (addr.ss_family == AF_INET6) {
    const auto& in6 = reinterpret_cast<const sockaddr_in6&>(addr);
    asio::ip::address_v6::bytes_type bytes;
    std::memcpy(bytes.data(), in6.sin6_addr.s6_addr, bytes.size());
    return asio::ip::address_v6(bytes, in6.sin6_scope_id).to_string();
  }
  throw std::runtime_error(what + " is not an IPv4 or IPv6 socket");
}

HttpServer::HttpServer(asio::io_context& ioc, asio::thread_pool& handlers, HttpHandler& handler, HttpServerOptions options)
    : state_(std::make_shared<State>(ioc, handlers, handler, std::move(options))) {
  fit_connections_to_descriptors(state_->opt.max_connections);
  auto& a = state_->acceptor;
  beast::error_code ec;
  if (const int fd = state_->opt.listen_fd; fd >= 0) {
    const auto addr = asio::ip::make_address(listening_address(fd), ec);
    if (ec) throw std::runtime_error("socket " + std::to_string(fd) + ": " + ec.message());
    ::fcntl(fd, F_SETFD, FD_CLOEXEC);  // not passed on to programs this one starts
    if (a.assign(addr.is_v6() ? tcp::v6() : tcp::v4(), fd, ec); ec)
      throw std::runtime_error("cannot serve on socket " + std::to_string(fd) + ": " + ec.message());
    return;
  }
  const std::string where = state_->opt.host + ":" + std::to_string(state_->opt.port);
  const auto addr = asio::ip::make_address(state_->opt.host, ec);
  if (ec) throw std::runtime_error("cannot listen on " + where + ": bad address: " + ec.message());
  const tcp::endpoint ep{addr, state_->opt.port};
  if (a.open(ep.protocol(), ec); ec) throw std::runtime_error("cannot listen on " + where + ": open: " + ec.message());
  if (a.set_option(asio::socket_base::reuse_address(true), ec); ec)
    throw std::runtime_error("cannot listen on " + where + ": SO_REUSEADDR: " + ec.message());
  if (a.bind(ep, ec); ec) throw std::runtime_error("cannot listen on " + where + ": bind: " + ec.message());
  if (a.listen(asio::socket_base::max_listen_connections, ec); ec)
    throw std::runtime_error("cannot listen on " + where + ": listen: " + ec.message());
}

HttpServer::~HttpServer() = default;

tcp::endpoint HttpServer::endpoint() const {
  beast::error_code ec;
  return state_->acceptor.local_endpoint(ec);
}

void HttpServer::start() {
  asio::dispatch(state_->acceptor.get_executor(), [st = state_] { accept_next(st); });
}

void HttpServer::shutdown() {
  state_->stopping = true;
  asio::post(state_->acceptor.get_executor(), [st = state_] {
    beast::error_code ec;
    st->acceptor.close(ec);
  });
  std::vector<std::shared_ptr<Session>> live;
  {
    std::lock_guard lock(state_->mu);
    for (auto& [id, w] : state_->sessions)
      if (auto s = w.lock()) live.push_back(std::move(s));
  }
  for (auto& s : live) s->stop_if_idle();
}

void HttpServer::reload_tls() {
  if (!state_->opt.tls.enabled()) return;
  auto fresh = make_server_tls_context(state_->opt.tls);
  std::lock_guard lock(state_->mu);
  state_->tls_context = std::move(fresh);
}

bool HttpServer::tls() const { return state_->opt.tls.enabled(); }

}  // namespace tessera::server
