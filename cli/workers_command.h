// `tessera workers`: look at a coordinator's workers and drain or undrain one.
#pragma once

#include "cli/coordinator_access.h"
#include "client/http_client.h"

#include <CLI/CLI.hpp>

#include <string>

namespace tessera::cli {

/// Options of `tessera workers`.
struct WorkersArgs {
  std::string action;       ///< ls, drain or undrain.
  std::string worker;       ///< The worker id (drain, undrain).
  CoordinatorAccess access;  ///< Coordinator URL, token and TLS files.
};

/// Registers the subcommand's options on `app`.
CLI::App* add_workers_command(CLI::App& app, WorkersArgs& args);

/// Runs it; returns the process exit code: 0 done, 2 refused by the coordinator (unknown id), 1 other errors.
int run_workers(const WorkersArgs& args);

}  // namespace tessera::cli
