// What the coordinator tells event subscribers (GET /v1/events): typed publishers over the event bus for job changes,
// tiles leased, done and failed, and workers seen and lost (found by comparing periodic looks at the workers).
#pragma once

#include "protocol/events.h"
#include "protocol/job.h"
#include "protocol/messages.h"
#include "protocol/worker.h"
#include "server/event_bus.h"

#include <map>
#include <mutex>
#include <string>
#include <vector>

namespace tessera::server {

/// Publishes farm events to a bus. Thread-safe.
class FarmEvents {
 public:
  /// Publishes to `bus` (which must outlive it).
  explicit FarmEvents(EventBus& bus) : bus_(bus) {}

  /// A job changed (state or priority): always published.
  void job(const protocol::JobStatus& status);
  /// Published only when the job's state differs from the last one published for it (e.g. queued -> running at
  /// its first lease).
  void job_if_state_changed(const protocol::JobStatus& status);
  /// True when `state` is the last state published for the job (job_if_state_changed would publish nothing), so a
  /// caller can skip taking the job's snapshot.
  bool published(const std::string& job, protocol::JobState state);
  /// A tile event (protocol::events::kTileLeased, kTileDone or kTileFailed).
  void tile(const char* name, const protocol::TileEvent& event);
  /// A sequence's frame was written (published after the frame's own job event).
  void frame_done(const protocol::FrameEvent& event);
  /// An ended job's rows were deleted (purged on request or by the retention sweep).
  void job_removed(const protocol::PurgeAnswer& purged);
  /// A worker was drained or undrained by an operator.
  void worker_drained(const protocol::WorkerInfo& worker, bool drained);
  /// A worker registered.
  void worker_registered(const protocol::WorkerInfo& worker);
  /// A periodic look at every worker: publishes worker_lost for those that went offline since the previous look and
  /// worker_seen (back) for those that returned (workers new since then were announced by worker_registered).
  void workers_checked(const std::vector<protocol::WorkerInfo>& workers);

 private:
  EventBus& bus_;
  std::mutex mu_;
  std::map<std::string, protocol::JobState> job_states_;      // last published state of unfinished jobs
  std::map<std::string, protocol::WorkerState> worker_states_;  // state at the previous look
};

}  // namespace tessera::server
