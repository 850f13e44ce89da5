#include "server/dependencies.h"

#include "server/farm_state.h"
#include "server/outbox.h"

#include <algorithm>
#include <deque>
#include <stdexcept>

namespace tessera::server {

namespace {

// A reason is cut here: a chain of blocked jobs quotes the reason of the job before it.
constexpr size_t kMaxReasonBytes = 1000;

std::string cut(std::string text) {
  if (text.size() > kMaxReasonBytes) text = text.substr(0, kMaxReasonBytes - 3) + "...";
  return text;
}

std::string join(const std::vector<std::string>& ids) {
  std::string out;
  for (const std::string& id : ids) out += (out.empty() ? "" : ", ") + id;
  return out;
}

// True for a job whose state its dependencies decide: it has some and has not started (held, or queued and never
// leased).
bool settles(const JobRec& j) {
  if (j.is_sequence() || j.status.params.pipeline.after.empty()) return false;
  return is_held(j.status.state) || (j.status.state == JobState::queued && !j.status.started_ms);
}

// What a job's dependencies say it should be: held (waiting or blocked, with the reason) or free to run (queued).
struct Verdict {
  JobState state = JobState::queued;
  std::optional<std::string> reason;
};

Verdict judge(const FarmState& s, const JobRec& j) {
  std::vector<std::string> open;
  for (const std::string& id : j.status.params.pipeline.after) {
    const auto it = s.jobs.find(id);
    if (it == s.jobs.end()) continue;  // purged: only a job nothing was held by can be, so it held nothing back
    const JobRec& d = *it->second;
    const JobState st = s.state_of(d);
    switch (st) {
      case JobState::done: break;
      case JobState::failed:
        return {JobState::blocked, cut("dependency " + id + " failed" +
                                       (d.is_sequence() ? "" : ": " + d.status.error.value_or("(no reason given)")))};
      case JobState::cancelled: return {JobState::blocked, cut("dependency " + id + " was cancelled")};
      case JobState::blocked:
        return {JobState::blocked, cut("dependency " + id + " is blocked: " + held_reason(s, d).value_or("?"))};
      default: open.push_back(id); break;
    }
  }
  if (!open.empty()) return {JobState::waiting, cut("waiting for " + join(open))};
  return {};
}

// Applies the verdict to a job that settles(); true when its state changed. With `now`, a job (or its sequence)
// newly blocked is a webhook event.
bool settle(FarmState& s, JobRec& j, std::optional<int64_t> now) {
  const Verdict v = judge(s, j);
  const JobState was = j.status.state;
  if (v.state == was && v.reason == j.status.reason) return false;
  const JobRec& shown = FarmState::top(j);
  const JobState shown_was = s.state_of(shown);
  j.status.state = v.state;
  j.status.reason = v.reason;
  s.touch(j);
  if (is_held(was) && !is_held(v.state)) {
    s.enqueue(j);
    s.work_appeared();
  } else if (!is_held(was) && is_held(v.state)) {
    s.dequeue(j);
  }
  if (now) note_job_event(s, shown, shown_was, *now);
  return was != v.state;
}

// Settles the jobs that wait for each id in `changed`, and the jobs that wait for those in turn.
void settle_from(FarmState& s, std::deque<std::string> changed, std::optional<int64_t> now) {
  std::set<std::string> seen(changed.begin(), changed.end());
  while (!changed.empty()) {
    const std::string id = std::move(changed.front());
    changed.pop_front();
    const std::set<std::string>* deps = s.dependents.dependents_of(id);
    if (!deps) continue;
    const std::vector<std::string> ids(deps->begin(), deps->end());  // settle() does not change the index
    for (const std::string& d : ids) {
      JobRec* dj = s.find_job(d);
      if (!dj || !settles(*dj) || !settle(s, *dj, now)) continue;
      for (const std::string& next : {dj->status.id, dj->sequence ? dj->sequence->status.id : std::string()})
        if (!next.empty() && seen.insert(next).second) changed.push_back(next);
    }
  }
}

// True when following `from`'s dependencies (and its frames') reaches `target` or a frame of it.
bool leads_to(const FarmState& s, const std::string& from, const std::string& target, std::set<std::string>& seen) {
  if (from == target || from.rfind(target + ".f", 0) == 0) return true;
  if (!seen.insert(from).second) return false;
  const auto it = s.jobs.find(from);
  if (it == s.jobs.end()) return false;
  for (const std::string& d : it->second->status.params.pipeline.after)
    if (leads_to(s, d, target, seen)) return true;
  for (const JobRec* f : it->second->frames)
    for (const std::string& d : f->status.params.pipeline.after)
      if (leads_to(s, d, target, seen)) return true;
  return false;
}

}  // namespace

void DependencyIndex::add(const JobRec& j) {
  if (j.is_sequence()) return;
  for (const std::string& d : j.status.params.pipeline.after) by_dependency_[d].insert(j.status.id);
}

void DependencyIndex::remove(const std::string& id) {
  by_dependency_.erase(id);
  for (auto it = by_dependency_.begin(); it != by_dependency_.end();) {
    it->second.erase(id);
    it = it->second.empty() ? by_dependency_.erase(it) : std::next(it);
  }
}

const std::set<std::string>* DependencyIndex::dependents_of(const std::string& id) const {
  const auto it = by_dependency_.find(id);
  return it == by_dependency_.end() ? nullptr : &it->second;
}

void check_dependencies(const FarmState& s, const std::string& id, const protocol::Pipeline& p,
                        const std::vector<int64_t>& frames) {
  if (p.per_frame && frames.empty())
    throw std::invalid_argument("per-frame dependencies apply only to a sequence: frame k waits for frame k");
  for (const std::string& d : p.after)
    if (d == id)
      throw std::invalid_argument("job " + id + " cannot wait for " + d + ": " + d +
                                  " is the job itself, a cycle that would never start");
  std::vector<std::string> unknown;
  for (const std::string& d : p.after)
    if (!s.jobs.count(d)) unknown.push_back(d);
  if (!unknown.empty())
    throw std::invalid_argument("cannot wait for " + join(unknown) + ": no such job" +
                                (unknown.size() > 1 ? "s" : "") + " on this coordinator");
  for (const std::string& d : p.after) {
    std::set<std::string> seen;
    if (leads_to(s, d, id, seen))
      throw std::invalid_argument("job " + id + " cannot wait for " + d + ": " + d + " waits for " + id +
                                  " itself, a cycle that would never start");
  }
  if (!p.per_frame) return;
  for (const std::string& d : p.after) {
    const JobRec& dj = *s.jobs.at(d);
    if (!dj.is_sequence())
      throw std::invalid_argument("per-frame dependencies need sequences: " + d + " is a one-image job");
    std::vector<int64_t> missing;
    for (const int64_t n : frames)
      if (!s.jobs.count(protocol::frame_job_id(d, n))) missing.push_back(n);
    if (!missing.empty()) {
      std::string list;
      for (size_t i = 0; i < missing.size() && i < 5; ++i) list += (i ? ", " : "") + std::to_string(missing[i]);
      if (missing.size() > 5) list += ", ...";
      throw std::invalid_argument("per-frame dependency " + d + " has no frame " + list + " (" +
                                  std::to_string(missing.size()) + " of this sequence's frames): frame k waits for "
                                  "frame k of each job it names");
    }
  }
}

std::vector<std::string> frame_dependencies(const protocol::Pipeline& p, int64_t number) {
  if (!p.per_frame) return p.after;
  std::vector<std::string> out;
  for (const std::string& d : p.after) out.push_back(protocol::frame_job_id(d, number));
  return out;
}

void hold_new_job(FarmState& s, JobRec& j, int64_t now) {
  if (j.status.params.pipeline.after.empty()) return;
  s.dependents.add(j);
  const Verdict v = judge(s, j);
  j.status.state = v.state;
  j.status.reason = v.reason;
  if (!j.sequence) note_job_event(s, j, JobState::queued, now);
}

void settle_dependents(FarmState& s, const JobRec& j, int64_t now) {
  std::deque<std::string> changed{j.status.id};
  if (j.sequence) changed.push_back(j.sequence->status.id);
  settle_from(s, std::move(changed), now);
}

void settle_retried(FarmState& s, JobRec& j, int64_t now) {
  if (settles(j)) settle(s, j, now);
  settle_dependents(s, j, now);
}

void restore_dependencies(FarmState& s) {
  s.dependents.clear();
  for (const auto& [id, j] : s.jobs) s.dependents.add(*j);
  std::deque<std::string> changed;
  for (auto& [id, j] : s.jobs)
    if (settles(*j) && settle(s, *j, std::nullopt)) changed.push_back(id);
  settle_from(s, std::move(changed), std::nullopt);  // a restart repairs; the events were stored with the changes
}

std::vector<std::string> held_dependents(const FarmState& s, const JobRec& j) {
  std::vector<std::string> out;
  std::vector<std::string> ids{j.status.id};
  for (const JobRec* f : j.frames) ids.push_back(f->status.id);
  for (const std::string& id : ids)
    if (const std::set<std::string>* deps = s.dependents.dependents_of(id))
      for (const std::string& d : *deps)
        if (const auto it = s.jobs.find(d); it != s.jobs.end() && is_held(it->second->status.state)) {
          const JobRec& top = *it->second;
          const std::string& shown = top.sequence ? top.sequence->status.id : top.status.id;
          if (std::find(out.begin(), out.end(), shown) == out.end()) out.push_back(shown);
        }
  return out;
}

std::vector<std::string> dependents_of(const FarmState& s, const JobRec& j) {
  std::set<const JobRec*> shown;
  const auto add = [&](const std::string& id) {
    if (const std::set<std::string>* deps = s.dependents.dependents_of(id))
      for (const std::string& d : *deps)
        if (const auto it = s.jobs.find(d); it != s.jobs.end())
          shown.insert(it->second->sequence && !j.sequence ? it->second->sequence : it->second.get());
  };
  add(j.status.id);
  for (const JobRec* f : j.frames) add(f->status.id);
  std::vector<const JobRec*> order(shown.begin(), shown.end());
  std::sort(order.begin(), order.end(), [](const JobRec* a, const JobRec* b) { return a->seq < b->seq; });
  std::vector<std::string> out;
  for (const JobRec* d : order) out.push_back(d->status.id);
  return out;  // in submission order
}

std::optional<std::string> held_reason(const FarmState& s, const JobRec& j) {
  if (!j.is_sequence()) return is_held(j.status.state) ? j.status.reason : std::nullopt;
  const JobState st = s.state_of(j);
  if (!is_held(st)) return std::nullopt;
  for (const JobRec* f : j.frames)
    if (f->status.state == st && f->status.reason) return "frame " + std::to_string(*f->status.frame) + ": " + *f->status.reason;
  return std::nullopt;
}

}  // namespace tessera::server
