// `tessera serve`: run the farm coordinator (HTTP API, tile scheduler, merge) on this machine.
#pragma once

#include "server/coordinator.h"

#include <CLI/CLI.hpp>

#include <chrono>
#include <string_view>

#include <cstddef>
#include <cstdint>
#include <string>

namespace tessera::cli {

/// The name `--durability` gives a durability.
std::string_view durability_name(server::Durability d);

/// Options of `tessera serve`: the coordinator's own options, filled in place (their defaults are its defaults),
/// and the texts and units the command line gives differently.
struct ServeArgs {
  server::CoordinatorOptions options;     ///< What the coordinator is told; the options below are turned into it.
  /// HOST:PORT to bind (port 0: ephemeral), or fd:N (an inherited socket).
  std::string listen = options.host + ":" + std::to_string(options.port);
  std::string data;                       ///< Data folder (blobs, jobs).
  std::string durability{durability_name(options.durability)};  ///< "machine", "process" or "none" (server/storage.h).
  std::string ready_file;                 ///< Written with the bound host:port once listening.
  double read_timeout_seconds = std::chrono::duration<double>(options.read_timeout).count();  ///< Whole-request read timeout.
  double retain_finished_hours = 0;       ///< Purge jobs this long after they ended (0: keep forever).
  /// Keep unreferenced blobs this long after their last upload or check.
  double blob_grace_minutes = double(options.limits.retention.blob_grace_ms) / 60'000.0;
  std::string client_token_file;          ///< File holding the client token (else $TESSERA_CLIENT_TOKEN).
  std::string users_file;                 ///< The users file (`tessera users`), re-read on SIGHUP.
  std::string worker_token_file;          ///< File holding the worker token (else $TESSERA_WORKER_TOKEN).
  bool verbose = false;                   ///< Debug logging.
  std::string webhook_secret_file;        ///< File holding the key webhook deliveries are signed with.
  double webhook_retry_seconds = 1;       ///< The wait before a delivery's second attempt (doubled for each next).
  double webhook_timeout_seconds = 10;    ///< One delivery attempt, connection to answer.
};

/// Registers the subcommand's options on `app`.
CLI::App* add_serve_command(CLI::App& app, ServeArgs& args);

/// Runs the coordinator until SIGINT/SIGTERM; returns the process exit code (errors are reported, never thrown).
int run_serve(const ServeArgs& args);

}  // namespace tessera::cli
