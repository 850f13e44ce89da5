#include "net/byte_stream.h"

#include <boost/asio/post.hpp>
#include <boost/beast/ssl/ssl_stream.hpp>

#include <utility>

namespace tessera::net {

namespace asio = boost::asio;
namespace beast = boost::beast;
using tcp = asio::ip::tcp;

namespace {

// A type-erased handler as the streams below see it: with no executor of its own, so it completes on the stream's.
// (Boost 1.81's any_completion_handler carries an any_completion_executor, which Beast's TCP stream cannot make
// non-blocking; the stream's executor is the one the HTTP operations above run on anyway.)
template <class Handler>
struct OnStreamExecutor {
  Handler handler;
  template <class... Args>
  void operator()(Args&&... args) {
    std::move(handler)(std::forward<Args>(args)...);
  }
};

template <class Handler>
OnStreamExecutor<Handler> on_stream(Handler handler) {
  return {std::move(handler)};
}

class PlainStream final : public ByteStream {
 public:
  explicit PlainStream(tcp::socket socket) : stream_(std::move(socket)) {}
  explicit PlainStream(executor_type executor) : stream_(std::move(executor)) {}
  beast::tcp_stream& lowest() override { return stream_; }
  SSL* tls_handle() override { return nullptr; }

 protected:
  void start_read(asio::mutable_buffer buffer, IoHandler handler) override {
    stream_.async_read_some(buffer, on_stream(std::move(handler)));
  }
  void start_write(std::vector<asio::const_buffer> buffers, IoHandler handler) override {
    stream_.async_write_some(buffers, on_stream(std::move(handler)));  // the operation keeps its own copy of the list
  }
  void start_handshake(asio::ssl::stream_base::handshake_type, DoneHandler handler) override { done_now(std::move(handler)); }
  void start_shutdown(DoneHandler handler) override { done_now(std::move(handler)); }

 private:
  void done_now(DoneHandler handler) {
    asio::post(stream_.get_executor(), [handler = std::move(handler)]() mutable { std::move(handler)(error_code{}); });
  }
  beast::tcp_stream stream_;
};

class TlsStream final : public ByteStream {
 public:
  TlsStream(tcp::socket socket, asio::ssl::context& context) : stream_(std::move(socket), context) {}
  TlsStream(executor_type executor, asio::ssl::context& context) : stream_(std::move(executor), context) {}
  beast::tcp_stream& lowest() override { return beast::get_lowest_layer(stream_); }
  SSL* tls_handle() override { return stream_.native_handle(); }

 protected:
  void start_read(asio::mutable_buffer buffer, IoHandler handler) override {
    stream_.async_read_some(buffer, on_stream(std::move(handler)));
  }
  void start_write(std::vector<asio::const_buffer> buffers, IoHandler handler) override {
    stream_.async_write_some(buffers, on_stream(std::move(handler)));  // small buffers are joined into one record
  }
  void start_handshake(asio::ssl::stream_base::handshake_type role, DoneHandler handler) override {
    stream_.async_handshake(role, on_stream(std::move(handler)));
  }
  void start_shutdown(DoneHandler handler) override { stream_.async_shutdown(on_stream(std::move(handler))); }

 private:
  beast::ssl_stream<beast::tcp_stream> stream_;
};

}  // namespace

std::unique_ptr<ByteStream> ByteStream::plain(tcp::socket socket) { return std::make_unique<PlainStream>(std::move(socket)); }

std::unique_ptr<ByteStream> ByteStream::plain(executor_type executor) {
  return std::make_unique<PlainStream>(std::move(executor));
}

std::unique_ptr<ByteStream> ByteStream::tls(tcp::socket socket, asio::ssl::context& context) {
  return std::make_unique<TlsStream>(std::move(socket), context);
}

std::unique_ptr<ByteStream> ByteStream::tls(executor_type executor, asio::ssl::context& context) {
  return std::make_unique<TlsStream>(std::move(executor), context);
}

}  // namespace tessera::net
