// `tessera worker`: lease tiles from a coordinator, render them, upload them.
#pragma once

#include "client/tls_client_context.h"
#include "core/scene/load_options.h"

#include <CLI/CLI.hpp>

#include <string>

namespace tessera::cli {

/// Options of `tessera worker`.
struct WorkerArgs {
  std::string coordinator;  ///< Coordinator URL.
  int threads = 0;          ///< Render threads (0: all cores, or one per --cpus entry).
  std::string cpus;         ///< CPU list the render threads are pinned to (empty: not pinned).
  std::string cache;        ///< Asset cache folder (empty: the default).
  std::string name;         ///< Worker name (empty: host-pid).
  std::string tags;         ///< Comma-separated tags offered to jobs' requirements.
  std::string token_file;   ///< File holding the worker token (else $TESSERA_WORKER_TOKEN).
  client::ClientTlsFiles tls; ///< CA and client certificate files for https:// coordinators.
  double connect_timeout_seconds = 3;   ///< Connecting and the TLS handshake.
  double request_timeout_seconds = 30;  ///< Sending a request, and receiving its response.
  int max_idle_wait_ms = 2000;          ///< Longest wait between lease requests when there is no work.
  int image_cache_mb = 1024;            ///< Decoded texture pixels kept across jobs, in MiB.
  double stop_timeout_seconds = 60;     ///< How long a stopping worker keeps trying to deliver its last upload.
  std::string preload;      ///< A job submission (JSON) whose scene is loaded at start (empty: none).
  AssetLimits asset_limits; ///< How large each image texture and mesh of a job may be.
  bool verbose = false;     ///< Debug logging.
};

/// Registers the subcommand's options on `app`.
CLI::App* add_worker_command(CLI::App& app, WorkerArgs& args);

/// Runs the worker until SIGTERM/SIGINT; returns the process exit code (0 after a clean stop).
int run_worker_command(const WorkerArgs& args);

}  // namespace tessera::cli
