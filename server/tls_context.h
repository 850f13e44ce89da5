// Server-side TLS settings: the OpenSSL context `serve --tls-cert/--tls-key/--tls-client-ca` builds from PEM files.
#pragma once

#include <boost/asio/ssl/context.hpp>

#include <memory>
#include <string>

namespace tessera::server {

/// The PEM files behind the coordinator's HTTPS listener (all empty: plain HTTP).
struct TlsServerFiles {
  std::string cert_file;       ///< Certificate chain, leaf first.
  std::string key_file;        ///< Private key of the leaf certificate.
  std::string client_ca_file;  ///< CA certificates a client certificate must chain to (empty: none asked for).

  /// True when the listener speaks TLS.
  bool enabled() const { return !cert_file.empty(); }
};

/// Reads the files into a fresh context: TLS 1.2 and 1.3 only, TLS 1.2 restricted to ECDHE key exchange with AEAD
/// ciphers, no compression or renegotiation; with client_ca_file every client must present a certificate that
/// chains to it. Throws std::runtime_error naming the file and OpenSSL's reason (missing file, bad PEM, key that
/// does not match the certificate, a key file without a certificate or the reverse).
std::shared_ptr<boost::asio::ssl::context> make_server_tls_context(const TlsServerFiles& files);

}  // namespace tessera::server
