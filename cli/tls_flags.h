// TLS flags of the commands that talk to a coordinator (`worker`, `submit`): trust and client certificate files.
#pragma once

#include "client/tls_client_context.h"

#include <CLI/CLI.hpp>

namespace tessera::cli {

/// Registers --ca-file, --tls-cert and --tls-key on `command`, filling `files`.
void add_client_tls_flags(CLI::App* command, client::ClientTlsFiles& files);

}  // namespace tessera::cli
