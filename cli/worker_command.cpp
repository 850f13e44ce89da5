#include "cli/worker_command.h"

#include "cli/asset_limit_flags.h"
#include "cli/exit_status.h"
#include "cli/tls_flags.h"
#include "cli/token.h"
#include "core/util/file_io.h"
#include "protocol/tags.h"

#include "worker/arena_pinning.h"
#include "worker/worker.h"

#include <spdlog/spdlog.h>

#include <algorithm>
#include <atomic>
#include <csignal>

namespace tessera::cli {

namespace {

std::atomic<int> g_stop_requests{0};
static_assert(std::atomic<int>::is_always_lock_free, "the signal handler needs a lock-free counter");

extern "C" void on_stop_signal(int) { g_stop_requests.fetch_add(1); }

}  // namespace

CLI::App* add_worker_command(CLI::App& app, WorkerArgs& a) {
  auto* c = app.add_subcommand("worker", "Run a worker that leases and renders tiles");
  c->add_option("--coordinator", a.coordinator, "Coordinator URL, e.g. http://127.0.0.1:8470 or https://coordinator.example:8470")->required();
  c->add_option("--threads", a.threads, "Render threads (default: all cores, or one per CPU of --cpus)")->check(CLI::Range(0, 4096));
  c->add_option("--cpus", a.cpus,
                "Pin render thread i to the i-th CPU of this list (e.g. 0-3 or 0,2): for a worker given whole cores, "
                "so that its threads, which sleep between tiles, never share one core while another is idle");
  c->add_option("--cache", a.cache, "Asset cache folder (default: $XDG_CACHE_HOME/tessera or ~/.cache/tessera)");
  c->add_option("--name", a.name, "Name reported to the coordinator (default: host name and process id)");
  c->add_option("--tags", a.tags,
                "What this worker offers, e.g. gpu,bigmem,site-a: jobs submitted with --require go only to workers "
                "with every tag they require (a-z, 0-9, '-', '_', '.'; changing them needs a restart)");
  c->add_option("--token-file", a.token_file, "File holding the worker token (default: $TESSERA_WORKER_TOKEN)");
  add_client_tls_flags(c, a.tls);
  c->add_option("--connect-timeout-seconds", a.connect_timeout_seconds,
                "A connection (with its TLS handshake) must be made within this time")
      ->check(CLI::Range(0.1, 3600.0))->capture_default_str();
  c->add_option("--request-timeout-seconds", a.request_timeout_seconds,
                "Sending a request, and receiving its whole response, must each take at most this long")
      ->check(CLI::Range(0.1, 86400.0))->capture_default_str();
  c->add_option("--max-idle-wait-ms", a.max_idle_wait_ms,
                "Longest wait for work per lease request while there is none: the coordinator holds the request "
                "that long (at most 10 s) and answers as soon as a tile is leasable (the waits double from 100 ms up "
                "to it, with jitter)")
      ->check(CLI::Range(1, 3'600'000))->capture_default_str();
  c->add_option("--image-cache-mb", a.image_cache_mb,
                "Decoded texture pixels kept in memory for later jobs that use the same image files (0: decode them "
                "for every job)")
      ->check(CLI::Range(0, 1'048'576))->capture_default_str();
  add_asset_limit_flags(c, a.asset_limits);
  c->add_option("--preload", a.preload,
                "A job submission (the JSON body of POST /v1/jobs) about to be leased, its assets already in --cache: "
                "its scene is loaded while the worker registers, and a leased job with the same scene, assets and "
                "loading settings renders from it (render --workers tells its workers the job it submits through a pipe; an "
                "empty file preloads nothing)")
      ->check(CLI::ExistingFile);
  c->add_option("--stop-timeout", a.stop_timeout_seconds,
                "Once asked to stop (SIGTERM), how long the worker keeps retrying the upload of its last tile while the "
                "coordinator does not take it, counted from the stop request or the end of the tile's render, whichever "
                "is later; it gives up sooner once the tile's lease has run out (the lease's length after its last "
                "answered heartbeat), logs \"giving up the upload of tile N of job J\" and exits 0 (a service manager's stop "
                "timeout must allow for the longest tile plus this)")
      ->check(CLI::Range(0.0, 86400.0))->capture_default_str();
  c->add_flag("-v,--verbose", a.verbose, "Debug logging");
  c->footer("SIGTERM or SIGINT: finish and upload the current tile (within --stop-timeout), then exit 0. A second "
            "one: stop rendering, hand the tile back, exit 0.");
  return c;
}

int run_worker_command(const WorkerArgs& a) {
  try {
    if (a.verbose) spdlog::set_level(spdlog::level::debug);
    struct sigaction sa {};
    sa.sa_handler = on_stop_signal;
    sigemptyset(&sa.sa_mask);
    sa.sa_flags = SA_RESTART;
    sigaction(SIGTERM, &sa, nullptr);
    sigaction(SIGINT, &sa, nullptr);
    std::signal(SIGPIPE, SIG_IGN);

    worker::WorkerOptions o;
    o.coordinator = a.coordinator;
    o.threads = a.threads;
    if (!a.cpus.empty()) {
      o.cpus = worker::parse_cpu_list(a.cpus);
      const std::vector<int> allowed = worker::allowed_cpus();
      for (int c : o.cpus)
        if (!std::binary_search(allowed.begin(), allowed.end(), c))
          throw std::invalid_argument("--cpus " + a.cpus + ": CPU " + std::to_string(c) + " is not one this process may run on");
      if (o.threads == 0) o.threads = int(o.cpus.size());
      if (size_t(o.threads) > o.cpus.size())
        throw std::invalid_argument("--threads " + std::to_string(o.threads) + " is more than the " +
                                    std::to_string(o.cpus.size()) + " CPU(s) of --cpus " + a.cpus);
    }
    o.cache_dir = a.cache;
    o.name = a.name;
    try {
      o.tags = protocol::parse_tag_list(a.tags, "--tags");
    } catch (const std::exception& e) {
      throw std::invalid_argument(std::string("--tags ") + a.tags + ": " + e.what());
    }
    o.token = load_token(a.token_file, "TESSERA_WORKER_TOKEN");
    o.tls = a.tls;
    o.max_idle_wait = std::chrono::milliseconds(a.max_idle_wait_ms);
    o.image_cache_bytes = size_t(a.image_cache_mb) << 20;
    o.asset_limits = a.asset_limits;
    o.stop_timeout = std::chrono::milliseconds(int64_t(a.stop_timeout_seconds * 1000));
    if (!a.preload.empty()) {
      try {
        // Read to its end, so that it can be a pipe; an empty one preloads nothing (render --workers closes the
        // pipe it gives when the job cannot be sent).
        const std::string job = read_file_bytes(a.preload);
        if (!job.empty()) o.preload = protocol::parse_job_submission(job);
      } catch (const std::exception& e) {
        throw std::invalid_argument("--preload " + a.preload + ": " + e.what());
      }
    }
    const auto ms = [](double s) { return std::chrono::milliseconds(int64_t(s * 1000)); };
    o.timeouts = client::HttpTimeouts{ms(a.connect_timeout_seconds), ms(a.request_timeout_seconds), ms(a.request_timeout_seconds)};
    worker::run_worker(o, g_stop_requests);
    return kExitOk;
  } catch (const std::exception& e) {
    spdlog::error("worker: {}", e.what());
    return kExitRefused;
  }
}

}  // namespace tessera::cli
