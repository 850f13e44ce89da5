#include "server/farm_events.h"

#include <nlohmann/json.hpp>

namespace tessera::server {

namespace ev = protocol::events;
using nlohmann::json;

namespace {

std::string dump(const json& j) { return j.dump(-1, ' ', false, json::error_handler_t::replace); }

}  // namespace

// Published under the lock, so the bus's order is the order of the recorded states.
void FarmEvents::job(const protocol::JobStatus& status) {
  std::lock_guard lock(mu_);
  job_states_[status.id] = status.state;
  bus_.publish(ev::kJob, dump(json(status)));
}

void FarmEvents::frame_done(const protocol::FrameEvent& event) { bus_.publish(ev::kFrameDone, dump(json(event))); }

void FarmEvents::job_if_state_changed(const protocol::JobStatus& status) {
  std::lock_guard lock(mu_);
  const auto it = job_states_.find(status.id);
  // A snapshot taken before the job ended can arrive after its end was published: it is stale, not a change.
  if (it != job_states_.end() && (it->second == status.state || protocol::is_final(it->second))) return;
  job_states_[status.id] = status.state;
  bus_.publish(ev::kJob, dump(json(status)));
}

bool FarmEvents::published(const std::string& job, protocol::JobState state) {
  std::lock_guard lock(mu_);
  const auto it = job_states_.find(job);
  return it != job_states_.end() && it->second == state;
}

void FarmEvents::tile(const char* name, const protocol::TileEvent& event) { bus_.publish(name, dump(json(event))); }

void FarmEvents::job_removed(const protocol::PurgeAnswer& purged) {
  std::lock_guard lock(mu_);
  job_states_.erase(purged.id);
  bus_.publish(ev::kJobRemoved, dump(json(purged)));
}

void FarmEvents::worker_drained(const protocol::WorkerInfo& worker, bool drained) {
  bus_.publish(ev::kWorkerChanged, dump(json(protocol::WorkerEvent{drained ? "draining" : "undrained", worker})));
}

void FarmEvents::worker_registered(const protocol::WorkerInfo& worker) {
  std::lock_guard lock(mu_);
  worker_states_[worker.id] = worker.state;
  bus_.publish(ev::kWorkerSeen, dump(json(protocol::WorkerEvent{"registered", worker})));
}

void FarmEvents::workers_checked(const std::vector<protocol::WorkerInfo>& workers) {
  std::lock_guard lock(mu_);
  std::map<std::string, protocol::WorkerState> now;  // the workers listed: forgotten ones are dropped
  for (const protocol::WorkerInfo& w : workers) {
    const auto it = worker_states_.find(w.id);
    const bool offline = w.state == protocol::WorkerState::offline;
    if (it != worker_states_.end()) {
      const bool was_offline = it->second == protocol::WorkerState::offline;
      if (offline && !was_offline) bus_.publish(ev::kWorkerLost, dump(json(protocol::WorkerEvent{"offline", w})));
      if (!offline && was_offline) bus_.publish(ev::kWorkerSeen, dump(json(protocol::WorkerEvent{"back", w})));
    }
    now.emplace(w.id, w.state);
  }
  worker_states_.swap(now);
}

}  // namespace tessera::server
