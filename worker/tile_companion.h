// The thread beside a tile's render: it keeps the tile's lease alive and asks for the worker's next lease before the
// render ends.
#pragma once

#include "client/http_client.h"
#include "worker/prefetched_lease.h"
#include "worker/render_signals.h"

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <functional>
#include <mutex>
#include <optional>
#include <string>
#include <thread>

namespace tessera::worker {

/// Heartbeats a tile's lease every `period` (the first beat after `first_beat`) on a thread of its own, as the worker
/// whose secret is `worker_secret`; on 410/404/403 it sets the render's cancel flag, and on a second stop request it cancels for shutdown. When asked (near the end of
/// the render) it also asks for the worker's next lease through `ask_lease`, so that the round trip overlaps the
/// render, and heartbeats that lease too until the worker takes it up. Lives as long as the tile's render.
class TileCompanion {
 public:
  /// Starts the thread; `prefix` begins its log lines, `lease` is the tile's lease id.
  TileCompanion(client::HttpClient& http, std::string prefix, std::string lease, std::string worker_secret,
                std::chrono::milliseconds period, std::chrono::milliseconds first_beat, RenderSignals& signals,
                const std::atomic<int>& stop_requests, std::function<std::optional<PrefetchedLease>()> ask_lease);
  /// Stops the thread (after a request in flight).
  ~TileCompanion();
  TileCompanion(const TileCompanion&) = delete;
  TileCompanion& operator=(const TileCompanion&) = delete;

  /// Asks for the next lease on the companion's thread (once; never blocks).
  void ask_next_lease();

  /// Whether finish() will hand over a next lease (unless a heartbeat finds it gone meanwhile): false when none was
  /// asked for, or the request got none; waits for the answer of a request under way. Called once the render has
  /// ended (no more asks).
  bool has_next_lease();

  /// Stops the thread (after a request in flight) and hands over the next lease, if one was granted and is still live.
  std::optional<PrefetchedLease> finish();

  /// When the last heartbeat of the tile's lease that the coordinator answered 200 came back (none yet: nullopt).
  std::optional<std::chrono::steady_clock::time_point> last_beat();

 private:
  void stop();
  void run() noexcept;
  // One heartbeat; false when the lease is gone (410/404) or not this worker's (403).
  bool beat(const std::string& lease, const std::string& body);

  client::HttpClient& http_;
  const std::string prefix_, lease_, secret_;
  const std::chrono::milliseconds period_, first_beat_;
  std::atomic<bool>& cancel_;
  std::atomic<int>& reason_;
  const std::atomic<uint64_t>& rays_;
  const std::atomic<int>& stop_requests_;
  const std::function<std::optional<PrefetchedLease>()> ask_lease_;
  std::mutex mutex_;
  std::condition_variable cv_;
  bool done_ = false;
  bool asked_ = false;                   // ask_next_lease was called
  bool answered_ = false;                // ask_lease_ returned (with next_ set when it granted a lease)
  std::optional<PrefetchedLease> next_;  // its answer, when a lease was granted
  std::optional<std::chrono::steady_clock::time_point> last_beat_;  // see last_beat()
  std::thread thread_;  // last: starts after every other member is ready
};

}  // namespace tessera::worker
