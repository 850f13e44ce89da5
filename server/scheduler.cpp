#include "server/scheduler.h"

#include "server/worker_secret.h"

#include <memory>
#include <stdexcept>
#include <type_traits>
#include <utility>

namespace tessera::server {

namespace {

ClockMs checked_clock(ClockMs clock) {
  if (!clock) throw std::invalid_argument("scheduler needs a clock");
  return clock;
}

SchedulerConfig checked_config(SchedulerConfig config) {
  if (config.lease_ms <= 0) throw std::invalid_argument("lease length must be positive");
  if (config.worker_failure_limit < 1) throw std::invalid_argument("the worker failure limit must be at least 1");
  if (config.tile_failure_workers < 1) throw std::invalid_argument("the tile failure workers must be at least 1");
  if (config.max_workers < 0) throw std::invalid_argument("the worker bound must not be negative");
  if (config.worker_retention_ms < 0) throw std::invalid_argument("the worker retention must not be negative");
  return config;
}

}  // namespace

Scheduler::Scheduler(SchedulerConfig config, ClockMs clock)
    : clock_(checked_clock(std::move(clock))), state_(checked_config(std::move(config)), nullptr) {}

Scheduler::Scheduler(SchedulerConfig config, ClockMs clock, SchedulerStore& store)
    : clock_(checked_clock(std::move(clock))), state_(checked_config(std::move(config)), &store) {
  std::lock_guard lock(mu_);
  restore(state_, store.load(), clock_());
  state_.changes.flush(state_);
}

Scheduler::~Scheduler() = default;

// Runs one operation under the lock: expired leases are reclaimed first, and everything the operation (and the
// reclaiming) changed goes to the store as one batch before the lock is released, as `store` says.
template <class F>
auto Scheduler::transact(F&& f, Store store, std::function<void()> durable) {
  std::unique_lock lock(mu_);
  const int64_t now = clock_();
  using R = std::invoke_result_t<F&, int64_t>;
  std::optional<R> r;
  try {
    leases_.expire(now);
    leases_.forget_workers(now);  // after expire(): a lease that just ran out holds its worker no longer
    r.emplace(f(now));
  } catch (...) {
    try {
      state_.changes.flush(state_);  // what changed before the failure still has to be stored
    } catch (...) {
    }
    throw;
  }
  if (store == Store::now) {
    state_.changes.flush(state_);
  } else if (store == Store::if_it_can) {
    try {
      state_.changes.flush(state_);
    } catch (const std::exception&) {
      // Kept in the change log: the next operation that stores (or store_pending) writes them.
    }
  }
  const bool due = state_.changes.take_sync_due();
  lock.unlock();
  // Outside the lock: other operations go on while the disk catches up. With `durable`, the caller does not wait
  // either: the store runs it once the flush is done.
  SchedulerStore* to = state_.changes.store();
  if (due && durable) to->sync_async(std::move(durable));
  else if (due) to->sync();
  else if (durable) durable();
  return std::move(*r);
}

std::string Scheduler::new_job_id() {
  return transact([&](int64_t) { return state_.next_id('j'); });
}

std::string Scheduler::add_job(const JobParams& params, const std::string& id) {
  JobControl::check_params(params);
  return transact([&](int64_t now) { return control_.add_job(params, id, now); });
}

std::string Scheduler::add_sequence(const JobParams& params, const std::vector<FrameParams>& frames,
                                    const std::string& id) {
  for (size_t i = 1; i < frames.size(); ++i)
    if (frames[i].number <= frames[i - 1].number)
      throw std::invalid_argument("frame " + std::to_string(frames[i].number) + " comes after frame " +
                                  std::to_string(frames[i - 1].number) + ": frames go in increasing number order");
  for (const FrameParams& f : frames) {
    JobParams p = params;
    p.width = f.width;
    p.height = f.height;
    p.spp = f.spp;
    try {
      JobControl::check_params(p);
    } catch (const std::invalid_argument& e) {
      throw std::invalid_argument("frame " + std::to_string(f.number) + ": " + e.what());
    }
  }
  return transact([&](int64_t now) { return control_.add_sequence(params, frames, id, now); });
}

std::optional<FramePage> Scheduler::frames(const std::string& id, std::optional<int64_t> after, size_t limit) {
  return transact([&](int64_t now) { return views_.frames(id, after, limit, now); }, Store::if_it_can);
}

std::optional<JobStatus> Scheduler::job(const std::string& id) {
  return transact([&](int64_t now) { return views_.job(id, now); }, Store::if_it_can);
}

std::vector<JobStatus> Scheduler::jobs() { return jobs(JobQuery{}).jobs; }

JobPage Scheduler::jobs(const JobQuery& query) {
  return transact([&](int64_t now) { return views_.jobs(query, now); }, Store::if_it_can);
}

std::optional<std::string> Scheduler::job_owner(const std::string& id) {
  return transact([&](int64_t) -> std::optional<std::string> {
    JobRec* j = state_.find_job(id);
    if (!j) return std::nullopt;
    return FarmState::top(*j).status.params.owner;
  }, Store::if_it_can);
}

std::optional<uint64_t> Scheduler::job_seq(const std::string& id) {
  return transact([&](int64_t) { return views_.job_seq(id); }, Store::if_it_can);
}

void Scheduler::set_shares(std::map<std::string, OwnerShare, std::less<>> shares) {
  transact(
      [&](int64_t) {
        state_.shares = std::move(shares);
        state_.work_appeared();  // a cap raised may let tiles be leased
        return true;
      },
      Store::later);
}

RegisterResult Scheduler::register_worker(const std::string& name, int64_t threads, const std::vector<std::string>& tags) {
  RegisterResult r;
  r.secret = new_worker_secret();
  const std::string hash = worker_secret_hash(r.secret);
  r.id = transact([&](int64_t now) { return leases_.register_worker(name, threads, tags, hash, now); });
  if (r.id.empty()) {
    r.status = RegisterResult::full;
    r.secret.clear();
  }
  return r;
}

WorkerCheck Scheduler::check_worker(const std::string& worker, std::string_view secret) {
  std::lock_guard lock(mu_);
  return leases_.check_worker(worker, secret);
}

WorkerCheck Scheduler::check_lease_holder(const std::string& lease, std::string_view secret, std::string* holder) {
  std::lock_guard lock(mu_);
  return leases_.check_lease_holder(lease, secret, holder);
}

std::optional<protocol::WorkerInfo> Scheduler::worker(const std::string& id) {
  return transact([&](int64_t now) { return views_.worker(id, now); });
}

std::vector<protocol::WorkerInfo> Scheduler::workers() {
  return transact([&](int64_t now) { return views_.workers(now); }, Store::if_it_can);
}

std::optional<protocol::WorkerInfo> Scheduler::set_drained(const std::string& worker, bool drained) {
  return transact([&](int64_t now) {
    return control_.set_drained(worker, drained) ? views_.worker(worker, now) : std::nullopt;
  });
}

bool Scheduler::has_worker(const std::string& id) {
  std::lock_guard lock(mu_);
  return state_.workers.contains(id);
}

AcquireResult Scheduler::acquire(const std::string& worker) {
  return transact([&](int64_t now) { return leases_.acquire(worker, now); });
}

int64_t Scheduler::leasable_tiles(const std::string& worker) {
  std::lock_guard lock(mu_);
  return leases_.leasable_tiles(worker);
}

HeartbeatResult Scheduler::heartbeat(const std::string& lease, uint64_t rays) {
  return transact([&](int64_t now) { return leases_.heartbeat(lease, rays, now); }, Store::if_it_can);
}

ResultClaim Scheduler::check_result(const std::string& lease) {
  return transact([&](int64_t) { return leases_.check_result(lease); }, Store::if_it_can);
}

ResultClaim Scheduler::claim_result(const std::string& lease) {
  // Stored with finish_result: a restart before it finds the tile as it was, which is the same.
  return transact([&](int64_t now) { return leases_.claim_result(lease, now); }, Store::later);
}

FinishResult Scheduler::finish_result(const std::string& lease, uint64_t rays, std::string_view pixels,
                                      std::vector<std::string> log) {
  std::pair<std::string, int64_t> tile;
  const FinishResult r =
      transact([&](int64_t now) { return leases_.finish_result(lease, rays, pixels, std::move(log), now, &tile); });
  std::lock_guard lock(mu_);  // transact returned after the flush
  leases_.flushed(tile.first, tile.second);
  return r;
}

void Scheduler::finish_result(const std::string& lease, uint64_t rays, std::string_view pixels,
                              std::vector<std::string> log, std::function<void(FinishResult)> durable) {
  // Set under the lock, before the store can run the continuation.
  auto result = std::make_shared<std::pair<FinishResult, std::pair<std::string, int64_t>>>();
  transact([&](int64_t now) {
             return result->first = leases_.finish_result(lease, rays, pixels, std::move(log), now, &result->second);
           },
           Store::now, [this, result, durable = std::move(durable)] {
             {
               std::lock_guard lock(mu_);
               leases_.flushed(result->second.first, result->second.second);
             }
             durable(result->first);
           });
}

void Scheduler::after_sync(std::function<void()> then) {
  if (SchedulerStore* store = state_.changes.store()) store->sync_async(std::move(then));
  else then();
}

void Scheduler::abandon_result(const std::string& lease) {
  // Called when storing the upload failed: the tile goes back to its lease whether or not the store takes it now.
  transact(
      [&](int64_t now) {
        leases_.abandon_result(lease, now);
        return 0;
      },
      Store::if_it_can);
}

FailResult Scheduler::fail(const std::string& lease, const std::string& error, const std::vector<std::string>& log) {
  return transact([&](int64_t now) { return leases_.fail(lease, error, log, now); });
}

bool Scheduler::release(const std::string& lease) {
  return transact([&](int64_t) { return leases_.release(lease); });
}

CancelResult Scheduler::cancel(const std::string& job) {
  return transact([&](int64_t now) { return control_.cancel(job, now); });
}

RetryResult Scheduler::retry(const std::string& job, const std::vector<int64_t>& frames) {
  return transact([&](int64_t now) { return control_.retry(job, frames, now); });
}

PauseResult Scheduler::pause(const std::string& job) {
  return transact([&](int64_t) { return control_.set_paused(job, true); });
}

PauseResult Scheduler::resume(const std::string& job) {
  return transact([&](int64_t) { return control_.set_paused(job, false); });
}

RequeueResult Scheduler::requeue(const std::string& job, int64_t tile) {
  return transact([&](int64_t) { return control_.requeue(job, tile); });
}

PriorityResult Scheduler::set_priority(const std::string& job, int priority) {
  return transact([&](int64_t) { return control_.set_priority(job, priority); });
}

RaiseResult Scheduler::raise_spp(const std::string& job, uint32_t spp) {
  return transact([&](int64_t now) { return control_.raise_spp(job, spp, now); });
}

PurgeResult Scheduler::purge(const std::string& job) {
  return transact([&](int64_t) { return control_.purge(job); }, Store::if_it_can);
}

void Scheduler::complete_job(const std::string& job) {
  transact([&](int64_t now) {
    control_.complete_job(job, now);
    return 0;
  });
}

void Scheduler::fail_job(const std::string& job, const std::string& error) {
  transact([&](int64_t now) {
    control_.fail_job(job, error, now);
    return 0;
  });
}

void Scheduler::expire() {
  transact([](int64_t) { return 0; }, Store::if_it_can);
}

void Scheduler::store_pending() {
  transact([](int64_t) { return 0; });
}

SchedulerCounters Scheduler::counters() {
  return transact([&](int64_t) { return views_.counters(); }, Store::if_it_can);
}

std::optional<protocol::TileList> Scheduler::tiles(const std::string& job) {
  return transact([&](int64_t) { return views_.tiles(job); }, Store::if_it_can);
}

std::vector<std::string> Scheduler::unfinalized_jobs() {
  return transact([&](int64_t) { return views_.unfinalized_jobs(); }, Store::if_it_can);
}

}  // namespace tessera::server
