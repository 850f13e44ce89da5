#include "cli/serve_command.h"

#include "cli/exit_status.h"
#include "cli/token.h"

#include "server/coordinator.h"
#include "server/storage.h"

#include <spdlog/spdlog.h>

namespace tessera::cli {

CLI::App* add_serve_command(CLI::App& app, ServeArgs& a) {
  auto* c = app.add_subcommand("serve", "Run the coordinator (HTTP API, tile scheduler, merge)");
  c->add_option("--listen", a.listen,
                "HOST:PORT to listen on (port 0 picks a free one), or fd:N to serve on the listening TCP socket "
                "inherited as descriptor N (systemd socket activation: fd:3); beyond loopback only with both tokens")
      ->capture_default_str();
  c->add_option("--data", a.data, "Data folder: blobs/, jobs/<id>/ (created if missing)")->required();
  c->add_option("--ready-file", a.ready_file, "Write the bound host:port here once listening");
  c->add_option("--durability", a.durability,
                "machine: acknowledged state is flushed to the disk first and survives a power cut; process: nothing "
                "is flushed, state survives a crash of the coordinator only; none: jobs, tiles and leases are kept "
                "in memory and a restart forgets them (for a coordinator that dies with the command that started "
                "it, as render --workers does; refused in a folder a durable coordinator has used)")
      ->check(CLI::IsMember({"machine", "process", "none"}))->capture_default_str();
  c->add_option("--lease-seconds", a.lease_seconds, "Lease length in seconds")->check(CLI::Range(0.05, 86400.0))->capture_default_str();
  c->add_option("--worker-failure-limit", a.worker_failure_limit,
                 "Failures on one job after which a worker is blocklisted for that job")
      ->check(CLI::Range(1, 1000))->capture_default_str();
  c->add_option("--tile-failure-workers", a.tile_failure_workers,
                "Distinct workers failing one tile that fail its job")
      ->check(CLI::Range(1, 1000))->capture_default_str();
  c->add_option("--heartbeat-seconds", a.heartbeat_seconds, "Heartbeat interval announced to workers")
      ->check(CLI::Range(1, 3600))->capture_default_str();
  c->add_option("--read-timeout-seconds", a.read_timeout_seconds, "A whole request must arrive within this time")
      ->check(CLI::Range(0.1, 3600.0))->capture_default_str();
  c->add_option("--threads", a.threads, "Request handler threads (0: all cores)")->check(CLI::Range(0, 1024));
  c->add_option("--client-token-file", a.client_token_file,
                "File holding the bearer token clients must send (default: $TESSERA_CLIENT_TOKEN)");
  c->add_option("--worker-token-file", a.worker_token_file,
                "File holding the bearer token workers must send (default: $TESSERA_WORKER_TOKEN)");
  c->add_option("--tls-cert", a.tls_cert, "Serve HTTPS with this PEM certificate chain (re-read on SIGHUP)");
  c->add_option("--tls-key", a.tls_key, "Private key (PEM) of --tls-cert (re-read on SIGHUP)");
  c->add_option("--tls-client-ca", a.tls_client_ca,
                "Require every client to present a certificate from this PEM CA file (mutual TLS; tokens still apply; re-read on SIGHUP)");
  c->add_option("--max-queued-jobs", a.max_queued_jobs, "Queued, running and paused jobs; more submissions get 429 with Retry-After")
      ->check(CLI::Range(int64_t(1), int64_t(1) << 40))->capture_default_str();
  c->add_option("--max-job-pixels", a.max_job_pixels, "Largest width x height of one job (400 above it)")
      ->check(CLI::Range(uint64_t(1), uint64_t(1) << 28))->capture_default_str();
  c->add_option("--max-job-samples", a.max_job_samples, "Largest width x height x spp of one job (400 above it)")
      ->check(CLI::Range(1.0, 1e18))->capture_default_str();
  c->add_option("--max-json-bytes", a.max_json_bytes, "Largest JSON request body (413 above it)")
      ->check(CLI::Range(std::size_t(1024), std::size_t(1) << 32))->capture_default_str();
  c->add_option("--max-blob-bytes", a.max_blob_bytes, "Largest asset upload (413 above it)")
      ->check(CLI::Range(std::size_t(1), std::size_t(1) << 40))->capture_default_str();
  c->add_option("--max-result-bytes", a.max_result_bytes, "Largest tile result upload (413 above it)")
      ->check(CLI::Range(std::size_t(1024), std::size_t(1) << 40))->capture_default_str();
  c->add_option("--max-header-bytes", a.max_header_bytes, "Largest request header (431 above it)")
      ->check(CLI::Range(std::size_t(1024), std::size_t(1) << 24))->capture_default_str();
  c->add_option("--max-connections", a.max_connections, "Open connections; more are answered 503 and closed")
      ->check(CLI::Range(std::size_t(1), std::size_t(1) << 20))->capture_default_str();
  c->add_option("--retain-finished-hours", a.retain_finished_hours,
                "Purge done, failed and cancelled jobs this many hours after they ended (default 0: keep them forever)")
      ->check(CLI::Range(0.0, 1e6));
  c->add_option("--blob-grace-minutes", a.blob_grace_minutes,
                "Delete an asset no job references only this many minutes after it was last uploaded or checked")
      ->check(CLI::Range(0.0, 1e8))->capture_default_str();
  c->add_option("--max-validations", a.max_validations,
                "Job submissions whose scenes are checked at once, on threads of their own (never the request handlers')")
      ->check(CLI::Range(1, 256))->capture_default_str();
  c->add_option("--validation-queue", a.validation_queue,
                "Submissions waiting for a check; more get 503 with Retry-After")
      ->check(CLI::Range(0, 4096))->capture_default_str();
  c->add_option("--max-event-streams", a.max_event_streams,
                "Open GET /v1/events streams; more are answered 503 (0: none, clients poll)")
      ->check(CLI::Range(std::size_t(0), std::size_t(1) << 16))->capture_default_str();
  c->add_flag("-v,--verbose", a.verbose, "Log every lease and connection event");
  return c;
}

int run_serve(const ServeArgs& a) {
  bool started = false;  // before coordinator.run(), an error means the coordinator did not start: refused
  try {
    if (a.verbose) spdlog::set_level(spdlog::level::debug);
    server::CoordinatorOptions o;
    server::set_listen_address(o, a.listen);
    o.data_dir = a.data;
    o.durability = a.durability == "process" ? server::Durability::process
                   : a.durability == "none"  ? server::Durability::none
                                             : server::Durability::machine;
    o.lease_seconds = a.lease_seconds;
    o.heartbeat_seconds = a.heartbeat_seconds;
    o.worker_failure_limit = a.worker_failure_limit;
    o.tile_failure_workers = a.tile_failure_workers;
    o.read_timeout = std::chrono::milliseconds(int64_t(a.read_timeout_seconds * 1000));
    o.handler_threads = a.threads;
    o.limits.max_queued_jobs = a.max_queued_jobs;
    o.limits.max_job_pixels = a.max_job_pixels;
    o.limits.max_job_samples = a.max_job_samples;
    o.limits.json_limit = a.max_json_bytes;
    o.limits.blob_limit = a.max_blob_bytes;
    o.limits.result_limit = a.max_result_bytes;
    if (a.retain_finished_hours > 0) o.limits.retention.retain_finished_ms = int64_t(a.retain_finished_hours * 3'600'000.0);
    o.limits.retention.blob_grace_ms = int64_t(a.blob_grace_minutes * 60'000.0);
    o.header_limit = a.max_header_bytes;
    o.max_connections = a.max_connections;
    o.admission.validations = a.max_validations;
    o.admission.queue = a.validation_queue;
    o.events.max_subscribers = a.max_event_streams;
    o.handle_signals = true;
    o.tls = server::TlsServerFiles{a.tls_cert, a.tls_key, a.tls_client_ca};
    o.limits.tokens.client = load_token(a.client_token_file, "TESSERA_CLIENT_TOKEN");
    o.limits.tokens.worker = load_token(a.worker_token_file, "TESSERA_WORKER_TOKEN");
    server::Coordinator coordinator(o);
    const auto ep = coordinator.endpoint();
    const std::string bound = ep.address().to_string() + ":" + std::to_string(ep.port());
    if (!o.tls.enabled() && !ep.address().is_loopback())
      spdlog::warn("serving plain HTTP on {}: access tokens and job data travel in clear text; use --tls-cert and "
                   "--tls-key unless this network is private to you (see README, Access and TLS)", bound);
    const auto& t = o.limits.tokens;
    spdlog::info("coordinator listening on {}://{} (data in {}{}, leases {}s, heartbeats {}s, tokens: {}{})",
                 o.tls.enabled() ? "https" : "http", bound, a.data,
                 o.durability == server::Durability::process ? " never flushed to the disk"
                 : o.durability == server::Durability::none  ? ", jobs kept in memory only"
                                                             : "",
                 a.lease_seconds,
                 a.heartbeat_seconds,
                 t.complete() ? "client and worker" : t.client.empty() ? (t.worker.empty() ? "none" : "worker only") : "client only",
                 o.tls.client_ca_file.empty() ? "" : ", client certificates required");
    if (!a.ready_file.empty()) write_file_atomic(a.ready_file, bound + "\n", server::flush_for(o.durability));  // after the log lines above
    started = true;
    coordinator.run();
    return kExitOk;
  } catch (const std::exception& e) {
    spdlog::error("serve: {}", e.what());
    return started ? kExitFailed : kExitRefused;
  }
}

}  // namespace tessera::cli
