// How the client commands (`submit`, `jobs`, `workers`) reach a coordinator: its URL, the client token and the TLS
// files, registered as flags once and turned into one authenticated HTTP client.
#pragma once

#include "client/http_client.h"
#include "client/tls_client_context.h"

#include <CLI/CLI.hpp>

#include <functional>
#include <memory>
#include <string>
#include <string_view>

namespace tessera::cli {

/// A coordinator and the client's credentials for it.
struct CoordinatorAccess {
  std::string coordinator;   ///< Coordinator URL.
  std::string token_file;    ///< File holding the client token (else $TESSERA_CLIENT_TOKEN).
  client::ClientTlsFiles tls;  ///< --ca-file, --tls-cert, --tls-key for https:// coordinators.

  /// A client for the coordinator sending the client token (when there is one); throws std::invalid_argument for a
  /// bad URL or TLS file and std::runtime_error for an unreadable token file.
  std::unique_ptr<client::HttpClient> client() const;
};

/// Runs `body` with a client for the coordinator and turns what it throws into the client commands' exit codes:
/// 2 (logged) for a request the coordinator refused (client::SubmitError), 1 (logged with `command`) for any other
/// failure; otherwise `body`'s own code.
int run_with_coordinator(const CoordinatorAccess& access, std::string_view command,
                         const std::function<int(client::HttpClient&)>& body);

/// Registers --coordinator (required), --token-file and the TLS flags on `command`, filling `access`.
void add_coordinator_access_flags(CLI::App* command, CoordinatorAccess& access);

}  // namespace tessera::cli
