// One connection's bytes, plain TCP or TLS, behind a single stream type. Beast's HTTP operations are templates over
// the stream and the completion handler: over this type they are compiled once, and the TLS layer's operations once
// each (in byte_stream.cpp), instead of once per stream type, HTTP operation and handler (which had made the server's
// and the client's HTTP files the slowest of the build).
#pragma once

#include <boost/asio/any_completion_handler.hpp>
#include <boost/asio/any_io_executor.hpp>
#include <boost/asio/async_result.hpp>
#include <boost/asio/buffer.hpp>
#include <boost/asio/ssl/context.hpp>
#include <boost/asio/ssl/stream_base.hpp>
#include <boost/beast/core/tcp_stream.hpp>

#include <cstddef>
#include <memory>
#include <vector>

namespace tessera::net {

/// The most Beast's HTTP reads ask of a stream at once (its own cap); they ask only for a buffer's free capacity, at
/// least 512 bytes, so a body read 512 bytes a system call unless this much room is kept free for it.
inline constexpr std::size_t kHttpReadBytes = 64 * 1024;

/// A Beast AsyncReadStream and AsyncWriteStream over plain TCP or TLS, with the TCP stream's timeouts underneath.
class ByteStream {
 public:
  using executor_type = boost::asio::any_io_executor;
  using error_code = boost::system::error_code;
  using IoHandler = boost::asio::any_completion_handler<void(error_code, std::size_t)>;
  using DoneHandler = boost::asio::any_completion_handler<void(error_code)>;

  /// A plain TCP stream over a connected socket.
  static std::unique_ptr<ByteStream> plain(boost::asio::ip::tcp::socket socket);
  /// A plain TCP stream, not yet connected, on `executor`.
  static std::unique_ptr<ByteStream> plain(executor_type executor);
  /// A TLS stream over a connected socket; `context` must outlive the stream.
  static std::unique_ptr<ByteStream> tls(boost::asio::ip::tcp::socket socket, boost::asio::ssl::context& context);
  /// A TLS stream, not yet connected, on `executor`; `context` must outlive the stream.
  static std::unique_ptr<ByteStream> tls(executor_type executor, boost::asio::ssl::context& context);

  virtual ~ByteStream() = default;
  /// The TCP stream underneath: connection, timeouts (expires_after) and the socket.
  virtual boost::beast::tcp_stream& lowest() = 0;
  /// The OpenSSL connection of a TLS stream; null for plain TCP.
  virtual SSL* tls_handle() = 0;
  /// The executor completions run on (the TCP stream's).
  executor_type get_executor() { return lowest().get_executor(); }

  /// Reads some bytes into the first non-empty buffer.
  template <class MutableBuffers, class Token>
  auto async_read_some(const MutableBuffers& buffers, Token&& token) {
    return boost::asio::async_initiate<Token, void(error_code, std::size_t)>(
        [this](IoHandler handler, boost::asio::mutable_buffer b) { start_read(b, std::move(handler)); }, token,
        first_buffer<boost::asio::mutable_buffer>(buffers));
  }

  /// Writes some bytes from the buffers.
  template <class ConstBuffers, class Token>
  auto async_write_some(const ConstBuffers& buffers, Token&& token) {
    std::vector<boost::asio::const_buffer> list;
    for (auto it = boost::asio::buffer_sequence_begin(buffers); it != boost::asio::buffer_sequence_end(buffers); ++it)
      if (boost::asio::const_buffer b(*it); b.size() > 0) list.push_back(b);
    return boost::asio::async_initiate<Token, void(error_code, std::size_t)>(
        [this](IoHandler handler, std::vector<boost::asio::const_buffer> list) {
          start_write(std::move(list), std::move(handler));
        },
        token, std::move(list));
  }

  /// The TLS handshake in the given role; on plain TCP it completes at once without an error.
  template <class Token>
  auto async_handshake(boost::asio::ssl::stream_base::handshake_type role, Token&& token) {
    return boost::asio::async_initiate<Token, void(error_code)>(
        [this](DoneHandler handler, boost::asio::ssl::stream_base::handshake_type r) {
          start_handshake(r, std::move(handler));
        },
        token, role);
  }

  /// Sends TLS close_notify and waits for the peer's; on plain TCP it completes at once without an error.
  template <class Token>
  auto async_shutdown(Token&& token) {
    return boost::asio::async_initiate<Token, void(error_code)>(
        [this](DoneHandler handler) { start_shutdown(std::move(handler)); }, token);
  }

 protected:
  virtual void start_read(boost::asio::mutable_buffer buffer, IoHandler handler) = 0;
  virtual void start_write(std::vector<boost::asio::const_buffer> buffers, IoHandler handler) = 0;
  virtual void start_handshake(boost::asio::ssl::stream_base::handshake_type role, DoneHandler handler) = 0;
  virtual void start_shutdown(DoneHandler handler) = 0;

 private:
  template <class Buffer, class Buffers>
  static Buffer first_buffer(const Buffers& buffers) {
    for (auto it = boost::asio::buffer_sequence_begin(buffers); it != boost::asio::buffer_sequence_end(buffers); ++it)
      if (Buffer b(*it); b.size() > 0) return b;
    return Buffer();
  }
};

}  // namespace tessera::net
