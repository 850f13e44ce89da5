// Client-side TLS settings: how `worker` and `submit` check an https:// coordinator (and prove who they are).
#pragma once

#include <boost/asio/ssl/context.hpp>

#include <memory>
#include <string>

namespace tessera::client {

/// PEM files for https:// URLs (all optional).
struct ClientTlsFiles {
  std::string ca_file;    ///< CA certificates to trust instead of the system store.
  std::string cert_file;  ///< Client certificate chain for a coordinator that asks for one (mutual TLS).
  std::string key_file;   ///< Private key of cert_file.

  /// True when any file is named.
  bool any() const { return !ca_file.empty() || !cert_file.empty() || !key_file.empty(); }
};

/// A context that verifies the server's certificate chain (against ca_file, else the system CA store) and speaks
/// TLS 1.2 or later; the host name or IP address is checked per connection by HttpClient. Throws std::runtime_error
/// naming the file and OpenSSL's reason when a file cannot be used.
std::shared_ptr<boost::asio::ssl::context> make_client_tls_context(const ClientTlsFiles& files);

}  // namespace tessera::client
