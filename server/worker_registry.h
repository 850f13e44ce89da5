// The registered workers: who they are, when each was last seen (presence), whether an operator drained it, and what
// each rendered since this coordinator started.
#pragma once

#include "protocol/messages.h"
#include "protocol/worker.h"

#include <cstdint>
#include <map>
#include <string>
#include <vector>

namespace tessera::server {

/// One registered worker as the scheduler keeps it.
struct WorkerRec {
  std::string name;          ///< Its self-reported name.
  int64_t last_seen_ms = 0;  ///< Register, lease request, heartbeat, upload or failure report.
  int64_t threads = 0;       ///< Announced at registration (0: unknown, e.g. after a restart).
  int64_t tiles_done = 0;    ///< Accepted uploads since this coordinator started.
  uint64_t rays = 0;         ///< Rays of those tiles.
  int64_t render_ms = 0;     ///< Their render times (lease grant to acceptance), summed.
  bool drained = false;      ///< No new leases.
  std::string secret_hash{};  ///< SHA-256 of its secret (server/worker_secret.h); "" for none: it must register again.
  std::string last_job{};     ///< The job of its latest lease (a sequence leased in any order keeps it there).
  std::vector<std::string> tags{};  ///< What it offers (sorted), as it registered; jobs requiring tags need them.
};

/// Every registered worker by id. Not thread-safe: the scheduler uses it under its lock.
class WorkerRegistry {
 public:
  /// A registry in which a worker not seen for `gone_ms` is no longer present.
  explicit WorkerRegistry(int64_t gone_ms) : gone_ms_(gone_ms) {}

  /// Adds (or replaces) the worker `id`.
  void add(const std::string& id, WorkerRec rec) { workers_[id] = std::move(rec); }
  /// The worker `id`, or nullptr when none is registered under it.
  WorkerRec* find(const std::string& id);
  /// The worker `id`, or nullptr when none is registered under it.
  const WorkerRec* find(const std::string& id) const;
  /// True when the worker id is registered.
  bool contains(const std::string& id) const { return workers_.count(id) > 0; }
  /// Registered workers.
  size_t size() const { return workers_.size(); }
  /// Every worker by id.
  const std::map<std::string, WorkerRec>& all() const { return workers_; }
  /// The worker's name, "" for an unknown id.
  std::string name_of(const std::string& id) const;

  /// Forgets the worker `id` (its id is never handed out again).
  void forget(const std::string& id) { workers_.erase(id); }

  /// Notes a request from the worker at `now` (unknown ids are ignored).
  void seen(const std::string& id, int64_t now);
  /// False once the worker has not been seen for the registry's gone_ms: it died or left.
  bool present(const WorkerRec& w, int64_t now) const { return now - w.last_seen_ms <= gone_ms_; }
  /// How long a worker stays present after its last request.
  int64_t gone_ms() const { return gone_ms_; }

  /// Adds an accepted tile to the worker's counts (unknown ids are ignored).
  void credit(const std::string& id, int64_t render_ms, uint64_t rays);
  /// Takes back a credit whose tile was not stored after all.
  void debit(const std::string& id, int64_t render_ms, uint64_t rays);

  /// The worker as GET /v1/workers shows it, from the lease it holds (nullptr: none) and the jobs it is blocklisted
  /// for, which the caller gathers.
  protocol::WorkerInfo info(const std::string& id, const WorkerRec& w, int64_t now, const protocol::Lease* holding,
                            std::vector<std::string> blocklisted_for) const;

 private:
  int64_t gone_ms_;
  std::map<std::string, WorkerRec> workers_;
};

}  // namespace tessera::server
