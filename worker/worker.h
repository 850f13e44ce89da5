// `tessera worker`: registers with a coordinator, leases tiles, renders them and uploads the results.
#pragma once

#include "client/http_client.h"
#include "protocol/messages.h"

#include <atomic>
#include <chrono>
#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

namespace tessera::worker {

/// How a worker runs.
struct WorkerOptions {
  std::string coordinator;             ///< Coordinator URL, e.g. http://127.0.0.1:8470.
  int threads = 0;                     ///< Render threads (0: all cores).
  std::vector<int> cpus;               ///< CPUs the render threads are pinned to, one per thread (empty: not pinned).
  std::filesystem::path cache_dir;     ///< Asset cache folder (empty: default_cache_dir()).
  std::string name;                    ///< Name sent at registration (empty: host name and pid).
  std::vector<std::string> tags;       ///< Tags sent at registration (protocol/tags.h): what the worker offers.
  std::string token;                   ///< Worker token sent as "Authorization: Bearer" (empty: none).
  size_t scene_cache_jobs = 3;         ///< Built scenes kept, one per job.
  size_t image_cache_bytes = size_t(1) << 30;  ///< Decoded texture pixels kept across jobs (0: decode for every job).
  AssetLimits asset_limits;            ///< How large each image texture and mesh of a job may be.
  std::chrono::milliseconds max_idle_wait{2000};   ///< Longest wait for work per lease request (held by the coordinator up to 10 s).
  std::chrono::milliseconds max_retry_wait{5000};  ///< Longest wait between retries when the coordinator is down.
  client::HttpTimeouts timeouts{};             ///< Timeouts of lease, spec, blob and upload requests.
  /// Once stopping, how long an upload the coordinator does not take is retried after the stop request or the end of
  /// its tile's render, whichever is later (it is given up sooner once its lease has run out).
  std::chrono::milliseconds stop_timeout{60'000};
  client::ClientTlsFiles tls;                  ///< Trust and client certificate files for an https:// coordinator.
  /// A job expected to be leased, whose assets are in the cache already: its scene is loaded at start, while the
  /// worker registers, and a leased job with the same scene, assets and loading settings renders from it.
  std::optional<protocol::JobSubmission> preload;
};

/// What a worker did, for its exit log and for tests.
struct WorkerStats {
  int64_t tiles_uploaded = 0;   ///< Results the coordinator accepted (or acknowledged as duplicates).
  int64_t tiles_dropped = 0;    ///< Tiles abandoned because the lease was revoked, unknown or the job ended.
  int64_t tiles_failed = 0;     ///< Tiles reported through /fail (or refused with 422).
  int64_t tiles_released = 0;   ///< Tiles handed back on shutdown.
  int64_t scenes_preloaded = 0; ///< Jobs that rendered from the scene of WorkerOptions::preload (0 or 1).
};

/// Runs the worker until *stop_requests becomes non-zero: the first request lets the current tile finish and upload
/// (an upload the coordinator does not take is given up after WorkerOptions::stop_timeout, or once its lease has run
/// out), a second one cancels the render and hands the tile back. Never returns because the coordinator is unreachable
/// (it retries with backoff and jitter); throws for bad options (URL, cache folder) and when the coordinator refuses
/// the worker token (401/403).
WorkerStats run_worker(const WorkerOptions& options, const std::atomic<int>& stop_requests);

}  // namespace tessera::worker
