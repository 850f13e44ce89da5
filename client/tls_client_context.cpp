#include "client/tls_client_context.h"

#include <openssl/ssl.h>

#include <filesystem>
#include <stdexcept>
#include <system_error>

namespace tessera::client {

namespace ssl = boost::asio::ssl;

std::shared_ptr<ssl::context> make_client_tls_context(const ClientTlsFiles& files) {
  if (files.cert_file.empty() != files.key_file.empty())
    throw std::runtime_error("a client certificate needs both --tls-cert and --tls-key");
  auto ctx = std::make_shared<ssl::context>(ssl::context::tls_client);
  ctx->set_options(ssl::context::default_workarounds | ssl::context::no_sslv2 | ssl::context::no_sslv3 |
                   ssl::context::no_tlsv1 | ssl::context::no_tlsv1_1 | ssl::context::no_compression);
  SSL_CTX_set_min_proto_version(ctx->native_handle(), TLS1_2_VERSION);
  ctx->set_verify_mode(ssl::verify_peer);
  std::string file;  // the one being read, for the message
  try {
    if (files.ca_file.empty()) {
      file = "(system CA store)";
      ctx->set_default_verify_paths();
    } else {
      file = files.ca_file;
      if (std::error_code ec; !std::filesystem::is_regular_file(file, ec))
        throw std::runtime_error("CA file '" + file + "' is not a readable file");
      ctx->load_verify_file(file);
    }
    if (!files.cert_file.empty()) {
      for (const std::string& f : {files.cert_file, files.key_file})
        if (std::error_code ec; !std::filesystem::is_regular_file(f, ec))
          throw std::runtime_error("TLS file '" + f + "' is not a readable file");
      file = files.cert_file;
      ctx->use_certificate_chain_file(file);
      file = files.key_file;
      ctx->use_private_key_file(file, ssl::context::pem);  // fails when the key does not match the certificate
    }
  } catch (const boost::system::system_error& e) {
    throw std::runtime_error("cannot use TLS file '" + file + "': " + e.code().message());
  }
  return ctx;
}

}  // namespace tessera::client
