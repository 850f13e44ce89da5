// `tessera serve`: run the farm coordinator (HTTP API, tile scheduler, merge) on this machine.
#pragma once

#include <CLI/CLI.hpp>

#include <cstddef>
#include <cstdint>
#include <string>

namespace tessera::cli {

/// Options of `tessera serve`.
struct ServeArgs {
  std::string listen = "127.0.0.1:8470";  ///< HOST:PORT to bind (port 0: ephemeral), or fd:N (an inherited socket).
  std::string data;                       ///< Data folder (blobs, jobs).
  std::string durability = "machine";     ///< "machine" (flushed before acknowledged) or "process" (never flushed).
  std::string ready_file;                 ///< Written with the bound host:port once listening.
  double lease_seconds = 30;              ///< Lease length.
  int worker_failure_limit = 2;           ///< Failures on one job after which a worker is blocklisted for it.
  int tile_failure_workers = 3;           ///< Distinct workers failing one tile that fail the job.
  int heartbeat_seconds = 5;              ///< Heartbeat interval announced to workers.
  double read_timeout_seconds = 30;       ///< Whole-request read timeout.
  int threads = 0;                        ///< Request handler threads (0: cores).
  std::string client_token_file;          ///< File holding the client token (else $TESSERA_CLIENT_TOKEN).
  std::string worker_token_file;          ///< File holding the worker token (else $TESSERA_WORKER_TOKEN).
  std::string tls_cert;                   ///< PEM certificate chain: serve HTTPS.
  std::string tls_key;                    ///< PEM private key of tls_cert.
  std::string tls_client_ca;              ///< PEM CA file: require client certificates from it (mutual TLS).
  int64_t max_queued_jobs = 1000;         ///< Queued plus running jobs before POST /v1/jobs answers 429.
  uint64_t max_job_pixels = uint64_t(1) << 26;  ///< width x height of one job.
  double max_job_samples = 4e10;          ///< width x height x spp of one job.
  std::size_t max_json_bytes = std::size_t(16) << 20;    ///< JSON request bodies.
  std::size_t max_blob_bytes = std::size_t(256) << 20;   ///< Blob uploads.
  std::size_t max_result_bytes = std::size_t(64) << 20;  ///< Tile result uploads.
  std::size_t max_header_bytes = 64 * 1024;              ///< Request headers.
  std::size_t max_connections = 1024;     ///< Open connections.
  double retain_finished_hours = 0;       ///< Purge jobs this long after they ended (0: keep forever).
  double blob_grace_minutes = 60;         ///< Keep unreferenced blobs this long after their last upload or check.
  int max_validations = 2;                ///< Job submissions checked at once (their own threads).
  int validation_queue = 8;               ///< Submissions waiting for a check before POST /v1/jobs answers 503.
  std::size_t max_event_streams = 64;     ///< Open event streams (0: none).
  bool verbose = false;                   ///< Debug logging.
};

/// Registers the subcommand's options on `app`.
CLI::App* add_serve_command(CLI::App& app, ServeArgs& args);

/// Runs the coordinator until SIGINT/SIGTERM; returns the process exit code (errors are reported, never thrown).
int run_serve(const ServeArgs& args);

}  // namespace tessera::cli
