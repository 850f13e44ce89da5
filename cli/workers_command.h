// `tessera workers`: look at a coordinator's workers and drain or undrain one.
#pragma once

#include "client/http_client.h"

#include <CLI/CLI.hpp>

#include <string>

namespace tessera::cli {

/// Options of `tessera workers`.
struct WorkersArgs {
  std::string action;       ///< ls, drain or undrain.
  std::string worker;       ///< The worker id (drain, undrain).
  std::string coordinator;  ///< Coordinator URL.
  std::string token_file;   ///< File holding the client token (else $TESSERA_CLIENT_TOKEN).
  farm::ClientTlsFiles tls;  ///< --ca-file, --tls-cert, --tls-key for https:// coordinators.
};

/// Registers the subcommand's options on `app`.
CLI::App* add_workers_command(CLI::App& app, WorkersArgs& args);

/// Runs it; returns the process exit code: 0 done, 2 refused by the coordinator (unknown id), 1 other errors.
int run_workers(const WorkersArgs& args);

}  // namespace tessera::cli
