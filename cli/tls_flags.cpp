#include "cli/tls_flags.h"

namespace tessera::cli {

void add_client_tls_flags(CLI::App* command, client::ClientTlsFiles& files) {
  command->add_option("--ca-file", files.ca_file,
                      "https:// only: trust the CA certificates in this PEM file instead of the system store");
  command->add_option("--tls-cert", files.cert_file,
                      "https:// only: client certificate (PEM) for a coordinator that requires one (--tls-client-ca)");
  command->add_option("--tls-key", files.key_file, "https:// only: private key (PEM) of --tls-cert");
}

}  // namespace tessera::cli
