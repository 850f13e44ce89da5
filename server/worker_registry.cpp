#include "server/worker_registry.h"

#include <algorithm>
#include <utility>

namespace tessera::server {

WorkerRec* WorkerRegistry::find(const std::string& id) {
  const auto it = workers_.find(id);
  return it == workers_.end() ? nullptr : &it->second;
}

const WorkerRec* WorkerRegistry::find(const std::string& id) const {
  const auto it = workers_.find(id);
  return it == workers_.end() ? nullptr : &it->second;
}

std::string WorkerRegistry::name_of(const std::string& id) const {
  const WorkerRec* w = find(id);
  return w ? w->name : std::string();
}

void WorkerRegistry::seen(const std::string& id, int64_t now) {
  if (WorkerRec* w = find(id)) w->last_seen_ms = std::max(w->last_seen_ms, now);
}

void WorkerRegistry::credit(const std::string& id, int64_t render_ms, uint64_t rays) {
  if (WorkerRec* w = find(id)) {
    ++w->tiles_done;
    w->rays += rays;
    w->render_ms += render_ms;
  }
}

void WorkerRegistry::debit(const std::string& id, int64_t render_ms, uint64_t rays) {
  if (WorkerRec* w = find(id)) {
    --w->tiles_done;
    w->rays -= rays;
    w->render_ms -= render_ms;
  }
}

protocol::WorkerInfo WorkerRegistry::info(const std::string& id, const WorkerRec& w, int64_t now,
                                          const protocol::Lease* holding,
                                          std::vector<std::string> blocklisted_for) const {
  protocol::WorkerInfo info;
  info.id = id;
  info.name = w.name;
  info.threads = w.threads;
  info.tiles_done = w.tiles_done;
  info.rays = w.rays;
  info.render_seconds = double(w.render_ms) / 1000.0;
  info.last_seen_ms = w.last_seen_ms;
  if (holding) {
    info.job = holding->job;
    info.tile = holding->tile;
  }
  info.blocklisted_for = std::move(blocklisted_for);
  info.tags = w.tags;
  using protocol::WorkerState;
  info.state = !present(w, now) ? WorkerState::offline
               : w.drained      ? WorkerState::draining
               : info.job       ? WorkerState::rendering
                                : WorkerState::idle;
  return info;
}

}  // namespace tessera::server
