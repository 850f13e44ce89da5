// Jobs that wait for other jobs (docs/protocol.md, "Dependencies"): who waits for whom, the checks of a new job's
// dependencies, and each held job's state (waiting, blocked, or released to the queue) settled from its dependencies'
// states whenever one of them changes. Runs under the scheduler's lock, inside the operation that changed the
// dependency, so a job and the jobs it holds back are stored in one change.
#pragma once

#include "server/scheduler_types.h"

#include <cstdint>
#include <map>
#include <set>
#include <string>
#include <vector>

namespace tessera::server {

struct FarmState;
struct JobRec;

/// Which jobs name which in their dependencies: for each job id, the jobs with tiles (one-image jobs, frames) that
/// wait for it. A sequence waits through its frames, so it is never in the index itself.
class DependencyIndex {
 public:
  /// Notes the job's dependencies (nothing for a sequence or a job without any).
  void add(const JobRec& j);
  /// The job is gone: as a dependent of others and as a dependency.
  void remove(const std::string& id);
  /// The jobs with tiles that name `id` (nullptr: none).
  const std::set<std::string>* dependents_of(const std::string& id) const;
  /// Forgets everything.
  void clear() { by_dependency_.clear(); }

 private:
  std::map<std::string, std::set<std::string>> by_dependency_;  // dependency id -> its dependents
};

/// Checks the dependencies of a job about to be added as `id` (`frames`: a sequence's frame numbers, else empty):
/// every id named exists, none is the job itself or leads back to it, and a per-frame dependency is a sequence with
/// each of the frames. Throws std::invalid_argument with the sentence answered.
void check_dependencies(const FarmState& s, const std::string& id, const protocol::Pipeline& p,
                        const std::vector<int64_t>& frames);
/// The dependencies of frame `number` of a sequence whose pipeline is `p`: frame `number` of each job in `after` when
/// per-frame, else the jobs themselves.
std::vector<std::string> frame_dependencies(const protocol::Pipeline& p, int64_t number);
/// Sets the state of a job just made (not yet in the queue) from its dependencies: waiting or blocked with its
/// reason, or left queued when they are all done. Notes it in the index. A one-image job blocked from the start is a
/// webhook event at `now` (a sequence's is noted once its frames are all added).
void hold_new_job(FarmState& s, JobRec& j, int64_t now);
/// Settles every job that waits for `j` (or for its sequence), and in turn those that wait for them, after j's state
/// changed: a job that has not started becomes waiting, blocked or queued again as its dependencies now say. A job
/// (or sequence) that becomes blocked is a webhook event (server/outbox.h) at `now`.
void settle_dependents(FarmState& s, const JobRec& j, int64_t now);
/// Settles `j` itself after it was put back in the queue (retried): waiting or blocked again when its dependencies
/// say so; then its dependents.
void settle_retried(FarmState& s, JobRec& j, int64_t now);
/// After a restart: the index rebuilt from the stored jobs and every job that has not started settled again.
void restore_dependencies(FarmState& s);
/// The jobs held back by `j` (waiting or blocked because of it), for a purge's refusal.
std::vector<std::string> held_dependents(const FarmState& s, const JobRec& j);
/// The jobs that name `j` (or a frame of it) as a dependency, as a snapshot lists them: a frame's sequence once.
std::vector<std::string> dependents_of(const FarmState& s, const JobRec& j);
/// Why a waiting or blocked job (a sequence: its first held frame) is held; nothing for other states.
std::optional<std::string> held_reason(const FarmState& s, const JobRec& j);

}  // namespace tessera::server
