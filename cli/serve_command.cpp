#include "cli/serve_command.h"

#include "cli/asset_limit_flags.h"
#include "cli/exit_status.h"
#include "cli/token.h"

#include "server/coordinator.h"
#include "core/util/enum_names.h"
#include "server/storage.h"

#include <spdlog/spdlog.h>

#include <fstream>

namespace tessera::cli {

namespace {
constexpr std::string_view kDurabilityNames[] = {"machine", "process", "none"};  // server::Durability's order
}  // namespace

std::string_view durability_name(server::Durability d) { return enum_name(d, kDurabilityNames); }

CLI::App* add_serve_command(CLI::App& app, ServeArgs& a) {
  server::CoordinatorOptions& o = a.options;
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
      ->check(CLI::IsMember(enum_names(kDurabilityNames)))->capture_default_str();
  c->add_option("--lease-seconds", o.lease_seconds, "Lease length in seconds")->check(CLI::Range(0.05, 86400.0))->capture_default_str();
  c->add_option("--worker-failure-limit", o.worker_failure_limit,
                 "Failures on one job after which a worker is blocklisted for that job")
      ->check(CLI::Range(1, 1000))->capture_default_str();
  c->add_option("--tile-failure-workers", o.tile_failure_workers,
                "Distinct workers failing one tile that fail its job")
      ->check(CLI::Range(1, 1000))->capture_default_str();
  c->add_option("--max-tile-log-bytes", o.job_tile_log_bytes,
                "Bytes of done tiles' logs kept per job; a tile's log beyond them is not kept, and counted (0: none)")
      ->check(CLI::Range(int64_t(0), int64_t(1) << 30))->capture_default_str();
  c->add_option("--heartbeat-seconds", o.limits.heartbeat_seconds, "Heartbeat interval announced to workers")
      ->check(CLI::Range(1, 3600))->capture_default_str();
  c->add_option("--read-timeout-seconds", a.read_timeout_seconds, "A whole request must arrive within this time")
      ->check(CLI::Range(0.1, 3600.0))->capture_default_str();
  c->add_option("--threads", o.handler_threads, "Request handler threads (0: all cores)")->check(CLI::Range(0, 1024));
  c->add_option("--client-token-file", a.client_token_file,
                "File holding the bearer token clients must send (default: $TESSERA_CLIENT_TOKEN)");
  c->add_option("--worker-token-file", a.worker_token_file,
                "File holding the bearer token workers must send (default: $TESSERA_WORKER_TOKEN)");
  c->add_option("--users", a.users_file,
                "Users file (made with `tessera users add`): named tokens with roles, shares and caps (re-read on SIGHUP)")
      ->check(CLI::ExistingFile);
  c->add_option("--webhook", o.webhooks,
                "POST every job's end (done, failed, cancelled) and blocking to this URL, at least once, from an outbox "
                "in the database (repeatable)");
  c->add_option("--webhook-allow", o.webhook_allow,
                "A URL prefix (scheme, host, port, path) a submission's own webhook (submit --notify) may name "
                "(repeatable; none: submissions name none)");
  c->add_option("--webhook-secret-file", a.webhook_secret_file,
                "File holding the key each delivery is signed with (HMAC-SHA256 of timestamp.body, header "
                "X-Tessera-Signature)");
  c->add_option("--webhook-attempts", o.webhook_sender.max_attempts,
                "Attempts of a delivery before it is marked failed")
      ->check(CLI::Range(1, 100))->capture_default_str();
  c->add_option("--webhook-retry-seconds", a.webhook_retry_seconds,
                "Wait before a delivery's second attempt, doubled for each next (up to 5 min), with jitter")
      ->check(CLI::Range(0.01, 3600.0))->capture_default_str();
  c->add_option("--webhook-timeout-seconds", a.webhook_timeout_seconds, "One delivery attempt, connection to answer")
      ->check(CLI::Range(0.1, 600.0))->capture_default_str();
  c->add_option("--ffmpeg", o.limits.steps.ffmpeg,
                "The encoder the movie step runs (submit --then movie): a path, or a name looked up on the "
                "coordinator's PATH; when there is none, movies are refused at submission")
      ->capture_default_str();
  c->add_option("--movie-stall-seconds", o.limits.steps.movie_stall_seconds,
                "An ffmpeg that reads no frame, or does not finish once fed, for this long is killed and the movie "
                "step failed with its log")
      ->check(CLI::Range(0.1, 86400.0))->capture_default_str();
  c->add_option("--tls-cert", o.tls.cert_file, "Serve HTTPS with this PEM certificate chain (re-read on SIGHUP)");
  c->add_option("--tls-key", o.tls.key_file, "Private key (PEM) of --tls-cert (re-read on SIGHUP)");
  c->add_option("--tls-client-ca", o.tls.client_ca_file,
                "Require every client to present a certificate from this PEM CA file (mutual TLS; tokens still apply; re-read on SIGHUP)");
  c->add_option("--max-queued-jobs", o.limits.max_queued_jobs, "Queued, running and paused jobs; more submissions get 429 with Retry-After")
      ->check(CLI::Range(int64_t(1), int64_t(1) << 40))->capture_default_str();
  c->add_option("--max-job-pixels", o.limits.max_job_pixels, "Largest width x height of one job (400 above it)")
      ->check(CLI::Range(uint64_t(1), uint64_t(1) << 28))->capture_default_str();
  c->add_option("--max-job-frames", o.limits.max_job_frames, "Most frames of one sequence (400 above it)")
      ->check(CLI::Range(int64_t(1), int64_t(1) << 30))->capture_default_str();
  c->add_option("--max-job-samples", o.limits.max_job_samples, "Largest width x height x spp of one job (400 above it)")
      ->check(CLI::Range(1.0, 1e18))->capture_default_str();
  add_asset_limit_flags(c, o.limits.assets);
  c->add_option("--max-json-bytes", o.limits.json_limit, "Largest JSON request body (413 above it)")
      ->check(CLI::Range(std::size_t(1024), std::size_t(1) << 32))->capture_default_str();
  c->add_option("--max-blob-bytes", o.limits.blob_limit, "Largest asset upload (413 above it)")
      ->check(CLI::Range(std::size_t(1), std::size_t(1) << 40))->capture_default_str();
  c->add_option("--max-result-bytes", o.limits.result_limit, "Largest tile result upload (413 above it)")
      ->check(CLI::Range(std::size_t(1024), std::size_t(1) << 40))->capture_default_str();
  c->add_option("--max-header-bytes", o.header_limit, "Largest request header (431 above it)")
      ->check(CLI::Range(std::size_t(1024), std::size_t(1) << 24))->capture_default_str();
  c->add_option("--max-connections", o.max_connections, "Open connections; more are answered 503 and closed")
      ->check(CLI::Range(std::size_t(1), std::size_t(1) << 20))->capture_default_str();
  c->add_option("--max-anonymous-per-address", o.peers.anonymous_per_address,
                "Connections one address may hold before sending a token; when every slot is taken, a new connection "
                "closes the oldest idle one of the address holding the most beyond this (0: a quarter of "
                "--max-connections)")
      ->check(CLI::Range(std::size_t(0), std::size_t(1) << 20))->capture_default_str();
  c->add_option("--max-refusals-per-minute", o.peers.refusals_per_minute,
                "401 and 403 answers one address may draw per minute; beyond, its connections get 429 until the "
                "minute ends (0: no limit)")
      ->check(CLI::Range(std::size_t(0), std::size_t(1) << 30))->capture_default_str();
  c->add_option("--max-workers", o.max_workers,
                "Registered workers; more registrations get 503 with Retry-After (offline workers are forgotten after "
                "--worker-retention-seconds)")
      ->check(CLI::Range(int64_t(1), int64_t(1) << 40))->capture_default_str();
  c->add_option("--max-registrations-per-minute", o.limits.registrations_per_minute,
                "Worker registrations taken a minute (up to a minute's worth at once); more get 429 with Retry-After")
      ->check(CLI::Range(0.01, 1e9))->capture_default_str();
  c->add_option("--worker-retention-seconds", o.worker_retention_seconds,
                "Forget a worker this long after its last request, once it is offline and holds no lease (it registers "
                "again if it comes back; 0: never)")
      ->check(CLI::Range(0.0, 1e9))->capture_default_str();
  c->add_option("--retain-finished-hours", a.retain_finished_hours,
                "Purge done, failed and cancelled jobs this many hours after they ended (default 0: keep them forever)")
      ->check(CLI::Range(0.0, 1e6));
  c->add_option("--blob-grace-minutes", a.blob_grace_minutes,
                "Delete an asset no job references only this many minutes after it was last uploaded or checked")
      ->check(CLI::Range(0.0, 1e8))->capture_default_str();
  c->add_option("--max-validations", o.admission.validations,
                "Job submissions whose scenes are checked at once, on threads of their own (never the request handlers')")
      ->check(CLI::Range(1, 256))->capture_default_str();
  c->add_option("--validation-queue", o.admission.queue,
                "Submissions waiting for a check; more get 503 with Retry-After")
      ->check(CLI::Range(0, 4096))->capture_default_str();
  c->add_option("--min-free-disk", o.min_free_disk,
                "Free bytes on the --data file system below which submissions and blob uploads get 507, so that "
                "running jobs keep room to finish (0: only once the disk is full)")
      ->check(CLI::Range(uint64_t(0), uint64_t(1) << 60))->capture_default_str();
  c->add_option("--max-event-streams", o.events.max_subscribers,
                "Open GET /v1/events streams; more are answered 503 (0: none, clients poll)")
      ->check(CLI::Range(std::size_t(0), std::size_t(1) << 16))->capture_default_str();
  c->add_flag("-v,--verbose", a.verbose, "Log every lease and connection event");
  return c;
}

namespace {

// The webhook signing key: the file's first line without surrounding blanks.
std::string load_secret_file(const std::string& file) {
  std::ifstream in(file);
  if (!in) throw std::runtime_error("cannot read the webhook secret file " + file);
  std::string line;
  std::getline(in, line);
  const size_t b = line.find_first_not_of(" \t\r\n");
  if (b == std::string::npos) throw std::runtime_error("the webhook secret file " + file + " is empty");
  return line.substr(b, line.find_last_not_of(" \t\r\n") - b + 1);
}

// The credentials a coordinator takes, for its start-up line: "client token, worker token, users file F" or "none".
std::string credentials_text(const server::AccessTokens& t) {
  std::string out;
  if (!t.client.empty()) out = "client token";
  if (!t.worker.empty()) out += (out.empty() ? "" : ", ") + std::string("worker token");
  if (!t.users_file.empty()) out += (out.empty() ? "" : ", ") + ("users file " + t.users_file.string());
  return out.empty() ? "none" : out;
}
}  // namespace

int run_serve(const ServeArgs& a) {
  bool started = false;  // before coordinator.run(), an error means the coordinator did not start: refused
  try {
    if (a.verbose) spdlog::set_level(spdlog::level::debug);
    server::CoordinatorOptions o = a.options;
    server::set_listen_address(o, a.listen);
    o.data_dir = a.data;
    o.durability = *enum_from_name<server::Durability>(a.durability, kDurabilityNames);  // checked by the parser
    o.read_timeout = std::chrono::milliseconds(int64_t(a.read_timeout_seconds * 1000));
    if (a.retain_finished_hours > 0) o.limits.retention.retain_finished_ms = int64_t(a.retain_finished_hours * 3'600'000.0);
    o.limits.retention.blob_grace_ms = int64_t(a.blob_grace_minutes * 60'000.0);
    o.handle_signals = true;
    o.limits.tokens.client = load_token(a.client_token_file, "TESSERA_CLIENT_TOKEN");
    o.limits.tokens.worker = load_token(a.worker_token_file, "TESSERA_WORKER_TOKEN");
    o.limits.tokens.users_file = a.users_file;
    if (!a.webhook_secret_file.empty()) o.webhook_sender.secret = load_secret_file(a.webhook_secret_file);
    o.webhook_sender.first_retry = std::chrono::milliseconds(int64_t(a.webhook_retry_seconds * 1000));
    o.webhook_sender.timeout = std::chrono::milliseconds(int64_t(a.webhook_timeout_seconds * 1000));
    server::Coordinator coordinator(o);
    const auto ep = coordinator.endpoint();
    const std::string bound = ep.address().to_string() + ":" + std::to_string(ep.port());
    if (!o.tls.enabled() && !ep.address().is_loopback())
      spdlog::warn("serving plain HTTP on {}: access tokens and job data travel in clear text; use --tls-cert and "
                   "--tls-key unless this network is private to you (see README, Access and TLS)", bound);
    const auto& t = o.limits.tokens;
    spdlog::info("coordinator listening on {}://{} (data in {}{}, leases {}s, heartbeats {}s, credentials: {}{})",
                 o.tls.enabled() ? "https" : "http", bound, a.data,
                 o.durability == server::Durability::process ? " never flushed to the disk"
                 : o.durability == server::Durability::none  ? ", jobs kept in memory only"
                                                             : "",
                 o.lease_seconds,
                 o.limits.heartbeat_seconds,
                 credentials_text(t),
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
