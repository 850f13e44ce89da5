#include "net/byte_stream.h"

#include <boost/asio/io_context.hpp>
#include <boost/asio/ip/tcp.hpp>
#include <boost/asio/ssl/context.hpp>
#include <boost/beast/core/flat_buffer.hpp>
#include <boost/beast/http/read.hpp>
#include <boost/beast/http/string_body.hpp>
#include <boost/beast/http/write.hpp>
#include <gtest/gtest.h>
#include <openssl/evp.h>
#include <openssl/pem.h>
#include <openssl/x509.h>
#include <openssl/x509v3.h>

#include <chrono>
#include <memory>
#include <string>

namespace tessera::net {
namespace {

namespace asio = boost::asio;
namespace beast = boost::beast;
namespace http = beast::http;
namespace ssl = asio::ssl;
using tcp = asio::ip::tcp;
using error_code = boost::system::error_code;

// A fresh key and a self-signed certificate for the address 127.0.0.1 (an IP SAN), in PEM, made in memory.
struct SelfSigned {
  std::string cert_pem, key_pem;
};

std::string to_pem(int (*write)(BIO*, void*), void* object) {
  BIO* bio = BIO_new(BIO_s_mem());
  write(bio, object);
  char* data = nullptr;
  const long n = BIO_get_mem_data(bio, &data);
  std::string pem(data, std::size_t(n));
  BIO_free(bio);
  return pem;
}

SelfSigned make_self_signed() {
  EVP_PKEY* key = EVP_PKEY_Q_keygen(nullptr, nullptr, "EC", "P-256");
  X509* cert = X509_new();
  X509_set_version(cert, 2);
  ASN1_INTEGER_set(X509_get_serialNumber(cert), 1);
  X509_gmtime_adj(X509_getm_notBefore(cert), -60);
  X509_gmtime_adj(X509_getm_notAfter(cert), 3600);
  X509_set_pubkey(cert, key);
  X509_NAME* name = X509_get_subject_name(cert);
  X509_NAME_add_entry_by_txt(name, "CN", MBSTRING_ASC, reinterpret_cast<const unsigned char*>("127.0.0.1"), -1, -1, 0);
  X509_set_issuer_name(cert, name);
  X509_EXTENSION* san = X509V3_EXT_conf_nid(nullptr, nullptr, NID_subject_alt_name, "IP:127.0.0.1");
  X509_add_ext(cert, san, -1);
  X509_EXTENSION_free(san);
  X509_sign(cert, key, EVP_sha256());
  SelfSigned out;
  out.cert_pem = to_pem([](BIO* b, void* c) { return PEM_write_bio_X509(b, static_cast<X509*>(c)); }, cert);
  out.key_pem = to_pem(
      [](BIO* b, void* k) { return PEM_write_bio_PrivateKey(b, static_cast<EVP_PKEY*>(k), nullptr, nullptr, 0, nullptr, nullptr); },
      key);
  X509_free(cert);
  EVP_PKEY_free(key);
  return out;
}

// What one exchange saw: the server's request body and the client's response body, and every error on the way.
struct Exchange {
  std::string request_body, response_body;
  error_code server_error, client_error;
  bool server_done = false, client_done = false;
};

// One HTTP request and its answer over a pair of ByteStreams on loopback (TLS when `tls`), the server echoing the
// request body reversed; bodies of `size` bytes (under Beast's default request limit of 1 MB), so that writes are
// split into several TLS records and partial writes.
// With `trusted` false the client trusts another certificate than the server's.
Exchange exchange(bool tls, std::size_t size, bool trusted = true) {
  asio::io_context ioc;
  const SelfSigned pem = make_self_signed();
  ssl::context server_ctx(ssl::context::tls_server), client_ctx(ssl::context::tls_client);
  server_ctx.use_certificate_chain(asio::buffer(pem.cert_pem));
  server_ctx.use_private_key(asio::buffer(pem.key_pem), ssl::context::pem);
  const std::string trust = trusted ? pem.cert_pem : make_self_signed().cert_pem;
  client_ctx.add_certificate_authority(asio::buffer(trust));
  client_ctx.set_verify_mode(ssl::verify_peer);

  tcp::acceptor acceptor(ioc, tcp::endpoint(asio::ip::make_address("127.0.0.1"), 0));
  Exchange ex;
  std::unique_ptr<ByteStream> server, client;
  beast::flat_buffer server_buffer, client_buffer;
  http::request<http::string_body> request{http::verb::post, "/echo", 11}, received;
  http::response<http::string_body> response{http::status::ok, 11}, answer;
  request.body().resize(size);
  for (std::size_t i = 0; i < size; ++i) request.body()[i] = char('a' + i % 26);
  request.prepare_payload();

  acceptor.async_accept([&](error_code ec, tcp::socket socket) {
    if (ec) return void(ex.server_error = ec);
    server = tls ? ByteStream::tls(std::move(socket), server_ctx) : ByteStream::plain(std::move(socket));
    server->lowest().expires_after(std::chrono::seconds(30));
    server->async_handshake(ssl::stream_base::server, [&](error_code hec) {
      if (hec) return void(ex.server_error = hec);
      http::async_read(*server, server_buffer, received, [&](error_code rec, std::size_t) {
        if (rec) return void(ex.server_error = rec);
        ex.request_body = received.body();
        response.body().assign(received.body().rbegin(), received.body().rend());
        response.prepare_payload();
        http::async_write(*server, response, [&](error_code wec, std::size_t) {
          if (wec) return void(ex.server_error = wec);
          server->async_shutdown([&](error_code) { ex.server_done = true; });
        });
      });
    });
  });

  client = tls ? ByteStream::tls(ioc.get_executor(), client_ctx) : ByteStream::plain(ioc.get_executor());
  if (SSL* handle = client->tls_handle()) X509_VERIFY_PARAM_set1_ip_asc(SSL_get0_param(handle), "127.0.0.1");
  client->lowest().expires_after(std::chrono::seconds(30));
  client->lowest().async_connect(acceptor.local_endpoint(), [&](error_code cec) {
    if (cec) return void(ex.client_error = cec);
    client->async_handshake(ssl::stream_base::client, [&](error_code hec) {
      if (hec) return void(ex.client_error = hec);
      http::async_write(*client, request, [&](error_code wec, std::size_t) {
        if (wec) return void(ex.client_error = wec);
        http::async_read(*client, client_buffer, answer, [&](error_code rec, std::size_t) {
          if (rec) return void(ex.client_error = rec);
          ex.response_body = answer.body();
          ex.client_done = true;
          client->async_shutdown([](error_code) {});  // answers the server's close_notify with its own
        });
      });
    });
  });
  ioc.run();
  return ex;
}

TEST(ByteStream, CarriesAnHttpExchangeOverPlainTcp) {
  const Exchange ex = exchange(false, 512 << 10);
  EXPECT_FALSE(ex.server_error) << ex.server_error.message();
  EXPECT_FALSE(ex.client_error) << ex.client_error.message();
  ASSERT_TRUE(ex.client_done);
  EXPECT_TRUE(ex.server_done);  // a plain stream's shutdown completes at once
  ASSERT_EQ(ex.request_body.size(), std::size_t(512) << 10);
  EXPECT_EQ(ex.response_body, std::string(ex.request_body.rbegin(), ex.request_body.rend()));
}

TEST(ByteStream, CarriesAnHttpExchangeOverTlsWithTheServerVerified) {
  const Exchange ex = exchange(true, 512 << 10);  // 32 TLS records each way
  EXPECT_FALSE(ex.server_error) << ex.server_error.message();
  EXPECT_FALSE(ex.client_error) << ex.client_error.message();
  ASSERT_TRUE(ex.client_done);
  EXPECT_TRUE(ex.server_done);
  ASSERT_EQ(ex.request_body.size(), std::size_t(512) << 10);
  EXPECT_EQ(ex.response_body, std::string(ex.request_body.rbegin(), ex.request_body.rend()));
}

TEST(ByteStream, AServerTheClientDoesNotTrustFailsTheHandshakeOnBothSides) {
  const Exchange ex = exchange(true, 16, /*trusted=*/false);
  EXPECT_NE(ex.client_error.message().find("certificate verify failed"), std::string::npos) << ex.client_error.message();
  EXPECT_TRUE(ex.server_error);
  EXPECT_FALSE(ex.client_done);
  EXPECT_TRUE(ex.request_body.empty());
}

TEST(ByteStream, TellsTlsFromPlain) {
  asio::io_context ioc;
  ssl::context ctx(ssl::context::tls_client);
  EXPECT_EQ(ByteStream::plain(ioc.get_executor())->tls_handle(), nullptr);
  EXPECT_NE(ByteStream::tls(ioc.get_executor(), ctx)->tls_handle(), nullptr);
}

}  // namespace
}  // namespace tessera::net
