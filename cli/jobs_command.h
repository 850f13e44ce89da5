// `tessera jobs`: look at and control a coordinator's jobs (ls, show, tiles, requeue, pause, resume, priority, retry, cancel).
#pragma once

#include "worker/http_client.h"

#include <CLI/CLI.hpp>

#include <optional>
#include <string>

namespace tessera::cli {

/// Options of `tessera jobs`.
struct JobsArgs {
  std::string action;       ///< ls, show, tiles, requeue, pause, resume, priority, retry or cancel.
  std::string job;          ///< The job id (all but ls).
  std::optional<int> priority;  ///< The new priority (priority), or the tile number (requeue).
  bool tiles = false;       ///< show: print the tile table too.
  std::string coordinator;  ///< Coordinator URL.
  std::string token_file;   ///< File holding the client token (else $TESSERA_CLIENT_TOKEN).
  farm::ClientTlsFiles tls;  ///< --ca-file, --tls-cert, --tls-key for https:// coordinators.
};

/// Registers the subcommand's options on `app`.
CLI::App* add_jobs_command(CLI::App& app, JobsArgs& args);

/// Runs it; returns the process exit code: 0 done, 2 refused by the coordinator (unknown id, wrong state), 1 other
/// errors (coordinator unreachable).
int run_jobs(const JobsArgs& args);

}  // namespace tessera::cli
