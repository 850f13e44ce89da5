// Test helper: a blocking reader of one GET /v1/events stream (chunked HTTP/1.1), returning its events one by one
// (server tests only). Reads time out after a generous safety limit so a broken server fails the test instead of
// hanging it; no test relies on that limit for its outcome.
#pragma once

#include <boost/asio/connect.hpp>
#include <boost/asio/ip/tcp.hpp>
#include <boost/asio/read.hpp>
#include <boost/asio/write.hpp>

#include <sys/socket.h>
#include <sys/time.h>

#include <cctype>
#include <optional>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

namespace tessera::server::testing {

/// One SSE message (comments are skipped).
struct SseEvent {
  std::string id;     ///< "id:" field (empty when absent).
  std::string event;  ///< "event:" field.
  std::string data;   ///< "data:" field.
};

/// Reads one event stream.
class SseReader {
 public:
  /// Connects and sends GET `target` with the given headers; status() and headers() then describe the answer.
  SseReader(boost::asio::ip::tcp::endpoint ep, const std::string& target,
            const std::vector<std::pair<std::string, std::string>>& headers = {}, int timeout_seconds = 60)
      : socket_(ioc_) {
    socket_.connect(ep);
    timeval tv{timeout_seconds, 0};
    ::setsockopt(socket_.native_handle(), SOL_SOCKET, SO_RCVTIMEO, &tv, sizeof tv);
    std::string req = "GET " + target + " HTTP/1.1\r\nHost: 127.0.0.1\r\nAccept: text/event-stream\r\n";
    for (const auto& [k, v] : headers) req += k + ": " + v + "\r\n";
    req += "\r\n";
    boost::asio::write(socket_, boost::asio::buffer(req));
    while (raw_.find("\r\n\r\n") == std::string::npos)
      if (!read_more()) throw std::runtime_error("the stream closed before its header");
    const size_t end = raw_.find("\r\n\r\n");
    head_ = raw_.substr(0, end);
    raw_.erase(0, end + 4);
    status_ = std::stoi(head_.substr(9, 3));
    chunked_ = head_.find("chunked") != std::string::npos;
  }

  /// The status code.
  int status() const { return status_; }
  /// The header block as text.
  const std::string& headers() const { return head_; }
  /// Body bytes so far (decoded); for answers that are not streams.
  std::string body() {
    std::string lower = head_;
    for (char& c : lower) c = char(std::tolower(static_cast<unsigned char>(c)));
    const size_t at = lower.find("content-length: ");
    const size_t want = at == std::string::npos ? std::string::npos : std::stoul(lower.substr(at + 16));
    decode();
    while (body_.size() < want && read_more()) decode();
    return body_;
  }
  /// Comments read so far (": ..." lines), in order.
  const std::vector<std::string>& comments() const { return comments_; }

  /// The next event, or nothing when the stream ended (or the safety limit passed). With `comments`, a message that
  /// is only a comment is returned too, as event ":" with the comment line as data.
  std::optional<SseEvent> next(bool comments = false) {
    for (;;) {
      decode();
      const size_t end = body_.find("\n\n");
      if (end != std::string::npos) {
        const std::string msg = body_.substr(0, end);
        body_.erase(0, end + 2);
        SseEvent e;
        bool any = false;
        size_t i = 0;
        while (i <= msg.size()) {
          size_t nl = msg.find('\n', i);
          if (nl == std::string::npos) nl = msg.size();
          const std::string line = msg.substr(i, nl - i);
          i = nl + 1;
          if (line.starts_with(":")) comments_.push_back(line);
          else if (line.starts_with("id: ")) e.id = line.substr(4), any = true;
          else if (line.starts_with("event: ")) e.event = line.substr(7), any = true;
          else if (line.starts_with("data: ")) e.data = line.substr(6), any = true;
        }
        if (any && !e.event.empty()) return e;
        if (comments && !any && msg.starts_with(":")) return SseEvent{"", ":", msg};
        continue;
      }
      if (ended_ || !read_more()) {
        decode();
        if (body_.find("\n\n") == std::string::npos) return std::nullopt;
      }
    }
  }

  /// The next event that is not one of `skip` (e.g. tile_leased while waiting for job events).
  std::optional<SseEvent> next_except(const std::vector<std::string>& skip) {
    for (;;) {
      auto e = next();
      if (!e) return e;
      bool skipped = false;
      for (const auto& s : skip) skipped |= e->event == s;
      if (!skipped) return e;
    }
  }

  /// True when the server ended the stream (last chunk or close) — reads until then.
  bool ended() {
    while (!ended_ && read_more()) decode();
    decode();
    return ended_ || eof_;
  }

  /// Closes the connection.
  void close() {
    boost::system::error_code ec;
    socket_.close(ec);
  }

 private:
  bool read_more() {
    if (eof_) return false;
    char buf[4096];
    boost::system::error_code ec;
    const size_t n = socket_.read_some(boost::asio::buffer(buf), ec);
    if (ec) {
      eof_ = true;
      return false;
    }
    raw_.append(buf, n);
    return true;
  }
  // Moves whole chunks from raw_ to body_.
  void decode() {
    if (!chunked_) {
      body_ += raw_;
      raw_.clear();
      if (eof_) ended_ = true;
      return;
    }
    for (;;) {
      const size_t crlf = raw_.find("\r\n");
      if (crlf == std::string::npos) return;
      const size_t size = std::stoul(raw_.substr(0, crlf), nullptr, 16);
      if (size == 0) {
        ended_ = true;
        raw_.clear();
        return;
      }
      if (raw_.size() < crlf + 2 + size + 2) return;
      body_ += raw_.substr(crlf + 2, size);
      raw_.erase(0, crlf + 2 + size + 2);
    }
  }

  boost::asio::io_context ioc_;
  boost::asio::ip::tcp::socket socket_;
  std::string raw_, head_, body_;
  std::vector<std::string> comments_;
  int status_ = 0;
  bool chunked_ = false, ended_ = false, eof_ = false;
};

}  // namespace tessera::server::testing
