#include "server/tls_context.h"

#include <openssl/ssl.h>

#include <filesystem>
#include <stdexcept>
#include <system_error>

namespace tessera::server {

namespace ssl = boost::asio::ssl;

namespace {

// Runs one of the context's file loaders, turning its failure into a message naming the file and OpenSSL's reason.
template <class Load>
void load(const std::string& file, const char* what, Load&& loader) {
  std::error_code fec;
  if (!std::filesystem::is_regular_file(file, fec))
    throw std::runtime_error(std::string(what) + " '" + file + "' is not a readable file");
  try {
    loader(file);
  } catch (const boost::system::system_error& e) {
    throw std::runtime_error(std::string("cannot use ") + what + " '" + file + "': " + e.code().message());
  }
}

}  // namespace

std::shared_ptr<ssl::context> make_server_tls_context(const TlsServerFiles& files) {
  if (files.cert_file.empty() != files.key_file.empty())
    throw std::runtime_error("TLS needs both --tls-cert and --tls-key");
  if (!files.enabled() && !files.client_ca_file.empty())
    throw std::runtime_error("--tls-client-ca needs --tls-cert and --tls-key");
  auto ctx = std::make_shared<ssl::context>(ssl::context::tls_server);
  SSL_CTX* native = ctx->native_handle();
  ctx->set_options(ssl::context::default_workarounds | ssl::context::no_sslv2 | ssl::context::no_sslv3 |
                   ssl::context::no_tlsv1 | ssl::context::no_tlsv1_1 | ssl::context::no_compression |
                   ssl::context::single_dh_use);
  SSL_CTX_set_options(native, SSL_OP_NO_RENEGOTIATION | SSL_OP_CIPHER_SERVER_PREFERENCE);
  SSL_CTX_set_min_proto_version(native, TLS1_2_VERSION);
  // TLS 1.2: forward-secret key exchange and AEAD ciphers only (TLS 1.3 suites are all of that kind already).
  if (SSL_CTX_set_cipher_list(native, "ECDHE-ECDSA-AES128-GCM-SHA256:ECDHE-RSA-AES128-GCM-SHA256:"
                                      "ECDHE-ECDSA-AES256-GCM-SHA384:ECDHE-RSA-AES256-GCM-SHA384:"
                                      "ECDHE-ECDSA-CHACHA20-POLY1305:ECDHE-RSA-CHACHA20-POLY1305") != 1)
    throw std::runtime_error("OpenSSL refused the TLS 1.2 cipher list");
  load(files.cert_file, "TLS certificate", [&](const std::string& f) { ctx->use_certificate_chain_file(f); });
  // OpenSSL checks here that the key belongs to the certificate ("key values mismatch" otherwise).
  load(files.key_file, "TLS key", [&](const std::string& f) { ctx->use_private_key_file(f, ssl::context::pem); });
  if (!files.client_ca_file.empty()) {
    load(files.client_ca_file, "TLS client CA", [&](const std::string& f) { ctx->load_verify_file(f); });
    if (STACK_OF(X509_NAME)* names = SSL_load_client_CA_file(files.client_ca_file.c_str()))
      SSL_CTX_set_client_CA_list(native, names);  // takes ownership; tells clients which CA to present a cert from
    ctx->set_verify_mode(ssl::verify_peer | ssl::verify_fail_if_no_peer_cert);
    // Session resumption with client certificates needs an id context, or OpenSSL refuses resumed sessions.
    static const unsigned char kSessionContext[] = "tessera";
    SSL_CTX_set_session_id_context(native, kSessionContext, sizeof kSessionContext - 1);
  }
  return ctx;
}

}  // namespace tessera::server
