#include "server/job_service.h"

#include "core/util/file_io.h"
#include "core/scene/scene_loader.h"
#include "core/image/tiles.h"
#include "core/render/layer_film.h"
#include "core/util/enum_names.h"
#include "server/layer_preview.h"
#include "failpoint/failpoint.h"
#include "server/tile_state.h"

#include <spdlog/spdlog.h>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <charconv>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <future>

namespace fs = std::filesystem;
using nlohmann::json;

namespace tessera::server {

using protocol::ApiError;

namespace {

std::string join_workers(const std::vector<std::string>& v) {
  std::string s;
  for (const auto& w : v) s += (s.empty() ? "" : ",") + w;
  return s;
}

// Asset paths are names for blobs (the coordinator and workers never open them as files), but a scene that renders
// here must render with `tessera render` too: the same paths the loader refuses are refused here.
void check_path(const std::string& rel, const std::string& where) {
  const fs::path p(rel);
  if (rel.empty()) throw ApiError(400, where + ": empty asset path");
  if (rel.find('\0') != std::string::npos) throw ApiError(400, where + ": asset path contains a NUL byte");
  if (p.is_absolute() || p.has_root_name() || p.has_root_directory())
    throw ApiError(400, where + ": absolute asset path '" + rel + "' (paths are relative to the scene's folder)");
  const fs::path n = p.lexically_normal();
  if (n.empty() || *n.begin() == "..") throw ApiError(400, where + ": asset path '" + rel + "' leaves the scene's folder");
}

}  // namespace

JobService::JobService(Scheduler& scheduler, BlobStore& blobs, JobStore& jobs, Metrics& metrics, ClockMs clock,
                       AdmissionLimits limits, FarmEvents& events, DiskSpace& disk, Background results)
    : sched_(scheduler), blobs_(blobs), jobs_(jobs), metrics_(metrics), clock_(std::move(clock)), limits_(limits),
      events_(events), disk_(disk), results_(at_once_if_empty(std::move(results))) {}

int64_t JobService::unfinished_jobs() {
  const SchedulerCounters c = sched_.counters();
  int64_t n = 0;
  for (const JobState st : {JobState::queued, JobState::running, JobState::paused, JobState::waiting, JobState::blocked})
    if (const auto it = c.jobs.find(st); it != c.jobs.end()) n += it->second;
  return n;
}

void JobService::check_assets(const json& scene, const std::map<std::string, std::string>& assets,
                              const std::string& where, const BlobFiles* known) {
  for (const auto& [path, sha] : assets) check_path(path, where + "assets[\"" + path + "\"]");
  const std::vector<std::string> used = scene_asset_paths(scene);
  for (const std::string& path : used) check_path(path, where + "scene");
  // Every asset the scene uses must be named and uploaded; say which are not, all at once.
  std::string missing;
  for (const std::string& path : used) {
    const auto it = assets.find(path);
    std::string why;
    if (it == assets.end()) why = "not in \"assets\"";
    else if (known ? !known->count(it->second) : !blobs_.has(it->second)) why = "not uploaded";
    else continue;
    missing += (missing.empty() ? "" : ", ") + path + " (" + why + ")";
  }
  if (!missing.empty()) throw ApiError(400, where + "missing assets: " + missing);
}

void JobService::check_samples(int width, int height, uint32_t per_pixel, bool adaptive) const {
  const double samples = double(width) * double(height) * double(per_pixel);
  if (samples <= limits_.max_job_samples) return;
  char text[256];
  std::snprintf(text, sizeof text,
                "job too large: %dx%d pixels x %u %s = %.3g samples is over the limit of %.3g (--max-job-samples)",
                width, height, per_pixel, adaptive ? "max_spp" : "spp", samples, limits_.max_job_samples);
  throw ApiError(400, text);
}

JobService::CheckedScene JobService::check_scene(const json& scene, const std::map<std::string, std::string>& assets,
                                                 const protocol::SamplingSettings& sampling, const std::string& where,
                                                 const BlobFiles* known, ObjParseCache* objs) {
  check_assets(scene, assets, where, known);
  TESSERA_FAIL_POINT("submit.validate");
  // The scene is checked as `tessera render` loads it, but not built: workers build their own BVH, and on a 2M-triangle
  // mesh the BVH was a quarter to a third of a whole load.
  LoadOptions check = sampling.load_options();
  check.build = false;
  check.checked_files = &checked_blobs_;  // a blob's file only ever holds the bytes its name hashes to
  check.mesh_digests = &mesh_digests_;
  check.obj_cache = objs;
  check.asset_limits = limits_.assets;
  LoadedScene loaded;
  try {
    loaded = load_scene_json(scene, "scene", [&](const std::string& rel, const std::string& jp) -> fs::path {
      const auto it = assets.find(rel);
      if (it == assets.end()) throw SceneError("scene: " + jp + ": asset '" + rel + "' is not in \"assets\"");
      std::optional<fs::path> f;
      if (!known) f = blobs_.file(it->second);
      else if (const auto k = known->find(it->second); k != known->end()) f = k->second;
      if (!f) throw SceneError("scene: " + jp + ": asset '" + rel + "' (" + it->second + ") is not uploaded");
      return *f;
    }, check);
  } catch (const SceneError& e) {
    throw ApiError(400, where + e.what());
  }
  const Scene& s = loaded.scene;
  // Size limits: the merged image is held in memory, and width x height x spp bounds the work one job may ask for.
  const uint64_t pixels = uint64_t(s.width) * uint64_t(s.height);
  if (pixels > limits_.max_job_pixels)
    throw ApiError(400, where + "job too large: " + std::to_string(s.width) + "x" + std::to_string(s.height) + " = " +
                            std::to_string(pixels) + " pixels is over the limit of " +
                            std::to_string(limits_.max_job_pixels) + " (--max-job-pixels)");
  const bool adaptive = sampling.target_error > 0.0;
  try {
    check_samples(s.width, s.height, adaptive ? sampling.max_spp : s.settings.spp, adaptive);
  } catch (const ApiError& e) {
    throw ApiError(400, where + e.what());
  }
  return {s.width, s.height, s.settings.spp, s.hash, std::move(loaded.warnings), layer_metadata(s, sampling.layers)};
}

ApiError JobService::queue_full() const {
  return ApiError(429, "too many unfinished jobs: " + std::to_string(limits_.max_queued_jobs) +
                           " are queued, running, paused, waiting or blocked (--max-queued-jobs); retry later");
}

namespace {
// What a submission fixes for its job (a sequence's, and each of its frames'), whatever its scenes hold.
JobParams submitted_params(const protocol::JobSubmission& sub, const std::string& owner) {
  JobParams p;
  p.name = sub.name;
  p.priority = sub.priority;
  p.tile_timeout_seconds = sub.tile_timeout_seconds;
  p.owner = owner;
  p.require = sub.require;
  p.max_workers = sub.max_workers;
  return p;
}
}  // namespace

protocol::SubmitAnswer JobService::submit(const protocol::JobSubmission& sub, const std::string& owner) {
  if (!sub.pipeline.notify.empty()) {
    try {
      limits_.notify_allowed.check(sub.pipeline.notify);
    } catch (const std::invalid_argument& e) {
      throw ApiError(403, e.what());
    }
  }
  for (const protocol::Step step : sub.pipeline.then) {
    if (step == protocol::Step::contact_sheet && sub.frames.empty())
      throw ApiError(400, "'then': contact_sheet needs a sequence ('frames'): it lays out its frames");
    if (step == protocol::Step::movie && sub.frames.empty())
      throw ApiError(400, "'then': movie needs a sequence ('frames'): it plays its frames in order");
    if (!steps_) throw ApiError(400, "'then': this coordinator runs no steps after the merge");
    if (step == protocol::Step::movie && !steps_->ffmpeg())
      throw ApiError(400, "'then': this coordinator cannot make the movie step: " + steps_->ffmpeg_missing() +
                              "; submit without it");
  }
  // Admission: queued plus running jobs are bounded (checked again, atomically with add_job, below).
  if (unfinished_jobs() >= limits_.max_queued_jobs) throw queue_full();
  if (!sub.frames.empty()) return submit_sequence(sub, owner);
  const CheckedScene s = check_scene(sub.scene, sub.assets, sub.sampling, "");
  JobParams p = submitted_params(sub, owner);
  p.width = s.width;
  p.height = s.height;
  p.tile_size = sub.tile_size;
  p.spp = s.spp;
  p.seed = sub.sampling.seed;
  p.scene_hash = s.hash;
  p.pipeline = sub.pipeline;

  protocol::JobSpec spec{sub.scene, sub.assets, sub.sampling, p.width, p.height, p.tile_size, sub.resumable};
  spec.sampling.spp = p.spp;
  std::unique_lock admit(admit_mu_);
  if (unfinished_jobs() >= limits_.max_queued_jobs) throw queue_full();
  check_assets(sub.scene, sub.assets, "");  // again, now that no blob collection can run before the job is stored
  const std::string id = sched_.new_job_id();
  // The record is the spec only: name, priority, size and times are the scheduler's (stored with the job's row).
  jobs_.save_record(id, spec);
  {
    std::lock_guard lock(mu_);
    cache_spec_locked(id, spec, true);
  }
  try {
    sched_.add_job(p, id);
  } catch (const std::invalid_argument& e) {  // its dependencies refused: the cached spec goes (the record is inert)
    std::lock_guard lock(mu_);
    specs_.erase(id);
    spec_json_.erase(id);
    throw ApiError(400, e.what());
  }
  admit.unlock();
  spdlog::info("job {}: submitted '{}' {}x{} spp {} seed {} tile {} priority {} ({} tiles)", id, p.name, p.width,
               p.height, p.spp, p.seed, p.tile_size, p.priority, TileGrid(p.width, p.height, p.tile_size).count());
  for (const auto& w : s.warnings) spdlog::warn("job {}: {}", id, w);
  announce(id);
  return {id, s.warnings};
}

protocol::SubmitAnswer JobService::submit_sequence(const protocol::JobSubmission& sub, const std::string& owner) {
  if (int64_t(sub.frames.size()) > limits_.max_job_frames)
    throw ApiError(400, "sequence too long: " + std::to_string(sub.frames.size()) + " frames is over the limit of " +
                            std::to_string(limits_.max_job_frames) + " (--max-job-frames)");
  if (sub.resumable)
    throw ApiError(400, "'resumable' applies to one-image jobs: a sequence's spp cannot be raised later");
  // A frame's assets: the submission's, with the paths the frame names itself replaced by its own.
  const auto assets_of = [&](const protocol::FrameSubmission& f) {
    if (f.assets.empty()) return sub.assets;
    std::map<std::string, std::string> a = f.assets;
    a.insert(sub.assets.begin(), sub.assets.end());  // keeps the frame's where both name a path
    return a;
  };
  // Every frame is checked before anything is stored: a submission is all its frames or none.
  const auto t0 = std::chrono::steady_clock::now();
  const size_t n = sub.frames.size();
  std::vector<FrameParams> frames(n);
  std::vector<std::string> records(n);  // each frame's spec as stored, JSON text
  std::vector<std::vector<std::string>> frame_warnings(n);
  std::vector<std::exception_ptr> refused(n);
  // Each distinct blob is looked up once, then the frames are checked on every core; the refusal answered is the
  // lowest-numbered frame's, whatever the order.
  std::set<std::string> named;  // every blob the submission names
  for (const auto& [path, sha] : sub.assets) named.insert(sha);
  for (const protocol::FrameSubmission& f : sub.frames)
    for (const auto& [path, sha] : f.assets) named.insert(sha);
  BlobFiles known;
  for (const std::string& sha : named)
    if (std::optional<fs::path> file = blobs_.file(sha)) known.emplace(sha, std::move(*file));
  ObjParseCache objs;  // the submission's meshes, each parsed once for all its frames
  tbb::parallel_for(tbb::blocked_range<size_t>(0, n), [&](const tbb::blocked_range<size_t>& r) {
    for (size_t i = r.begin(); i != r.end(); ++i) {
      const protocol::FrameSubmission& f = sub.frames[i];
      const std::string where = "frame " + std::to_string(f.number) + ": ";
      try {
        const std::map<std::string, std::string> assets = assets_of(f);
        CheckedScene s = check_scene(f.scene, assets, sub.sampling, where, &known, &objs);
        frames[i] = {f.number, s.width, s.height, s.spp, s.hash};
        protocol::JobSpec spec{f.scene, assets, sub.sampling, s.width, s.height, sub.tile_size, false};
        spec.sampling.spp = s.spp;
        records[i] = json(spec).dump();
        for (std::string& w : s.warnings) frame_warnings[i].push_back(where + w);
      } catch (...) {
        refused[i] = std::current_exception();
      }
    }
  });
  for (const std::exception_ptr& e : refused)
    if (e) std::rethrow_exception(e);
  if (std::find(sub.pipeline.then.begin(), sub.pipeline.then.end(), protocol::Step::movie) != sub.pipeline.then.end())
    for (const FrameParams& f : frames)
      if (f.width != frames.front().width || f.height != frames.front().height)
        throw ApiError(400, "'then': movie needs frames of one size: frame " + std::to_string(f.number) + " is " +
                                std::to_string(f.width) + "x" + std::to_string(f.height) + ", frame " +
                                std::to_string(frames.front().number) + " " + std::to_string(frames.front().width) +
                                "x" + std::to_string(frames.front().height));
  std::vector<std::string> warnings;
  for (auto& w : frame_warnings) warnings.insert(warnings.end(), w.begin(), w.end());
  JobParams p = submitted_params(sub, owner);
  p.tile_size = sub.tile_size;
  p.spp = frames.front().spp;
  p.seed = sub.sampling.seed;
  p.frame_order = sub.frame_order;
  p.pipeline = sub.pipeline;
  std::unique_lock admit(admit_mu_);
  if (unfinished_jobs() >= limits_.max_queued_jobs) throw queue_full();
  // Again, now that no blob collection can run before the job is stored: each distinct blob once, and the frames'
  // own sentence only when one went meanwhile.
  if (!std::all_of(named.begin(), named.end(), [&](const std::string& b) { return blobs_.has(b); }))
    for (const protocol::FrameSubmission& f : sub.frames)
      check_assets(f.scene, assets_of(f), "frame " + std::to_string(f.number) + ": ");
  const auto t_checked = std::chrono::steady_clock::now();
  const std::string id = sched_.new_job_id();
  // The frames' specs are stored, not cached: a frame's is read (and cached) when a worker first needs it.
  std::vector<std::pair<std::string, std::string>> rows;
  rows.reserve(n);
  for (size_t i = 0; i < n; ++i) rows.emplace_back(frame_job_id(id, frames[i].number), std::move(records[i]));
  jobs_.save_record_texts(rows);
  try {
    sched_.add_sequence(p, frames, id);
  } catch (const std::invalid_argument& e) {
    throw ApiError(400, e.what());
  }
  admit.unlock();
  int64_t tiles = 0;
  for (const FrameParams& f : frames) tiles += TileGrid(f.width, f.height, p.tile_size).count();
  const auto seconds = [](auto a, auto b) { return std::chrono::duration<double>(b - a).count(); };
  spdlog::info("job {}: submitted sequence '{}' of {} frames ({} to {}), {} tiles, spp {} seed {} tile {} priority {} "
               "frame order {} (checked in {:.3f} s, stored in {:.3f} s)", id, p.name, frames.size(),
               frames.front().number, frames.back().number, tiles, p.spp, p.seed, p.tile_size, p.priority,
               to_string(p.frame_order), seconds(t0, t_checked), seconds(t_checked, std::chrono::steady_clock::now()));
  for (const auto& w : warnings) spdlog::warn("job {}: {}", id, w);
  announce(id);
  return {id, warnings};
}

void JobService::refuse_frame(const std::string& id, const char* what) {
  const protocol::JobStatus s = status(id);
  if (!s.sequence) return;
  throw ApiError(409, "job " + id + " is frame " + std::to_string(*s.frame) + " of sequence " + *s.sequence +
                          ": " + what + " the sequence (a retry can name frames: {\"frames\": [" +
                          std::to_string(*s.frame) + "]})");
}

protocol::FrameList JobService::frames(const std::string& id, const protocol::FrameListQuery& q) {
  auto page = sched_.frames(id, q.after, q.limit);
  if (!page) {
    status(id);  // 404 for an unknown job
    throw ApiError(409, "job " + id + " is not a sequence: it has no frames");
  }
  protocol::FrameList out{std::move(page->frames), std::nullopt};
  if (page->more) out.next = *out.frames.back().frame;
  return out;
}

std::string JobService::frame_job(const std::string& id, const std::string& frame) {
  int64_t n = -1;
  const auto [end, ec] = std::from_chars(frame.data(), frame.data() + frame.size(), n);
  const protocol::JobStatus s = status(id);
  if (!s.frames) throw ApiError(409, "job " + id + " is not a sequence: it has no frames");
  if (ec != std::errc() || end != frame.data() + frame.size() || n < 0 || !sched_.job(frame_job_id(id, n)))
    throw ApiError(404, "job " + id + " has no frame '" + frame + "' (its frames are numbered " +
                            std::to_string(s.frames->first) + " to " + std::to_string(s.frames->last) + ")");
  return frame_job_id(id, n);
}

protocol::JobStatus JobService::status(const std::string& id) {
  auto s = sched_.job(id);
  if (!s) throw ApiError(404, "no job " + id);
  if (steps_ && !s->params.pipeline.then.empty()) s->outputs = steps_->outputs(*s);
  return std::move(*s);
}

std::vector<protocol::JobStatus> JobService::list() { return sched_.jobs(); }

protocol::JobList JobService::list(const protocol::JobListQuery& q) {
  JobQuery query;
  query.states.insert(q.states.begin(), q.states.end());
  query.limit = q.limit;
  query.owner = q.owner;
  if (!q.after.empty()) {
    query.after = sched_.job_seq(q.after);
    uint64_t seq = 0;
    const char* end = q.after.data() + q.after.size();
    if (!query.after && q.after.size() > 1 && q.after[0] == 'c') {
      const auto [ptr, ec] = std::from_chars(q.after.data() + 1, end, seq);
      if (ec == std::errc() && ptr == end) query.after = seq;
    }
    if (!query.after)
      throw ApiError(400, "after: '" + q.after + "' is neither the \"next\" cursor of a listing nor a job id");
  }
  JobPage page = sched_.jobs(query);
  protocol::JobList out{std::move(page.jobs), std::nullopt};
  if (page.more) out.next = "c" + std::to_string(page.seqs.back());
  return out;
}

protocol::JobStatus JobService::cancel(const std::string& id) {
  refuse_frame(id, "cancel");
  const CancelResult c = sched_.cancel(id);
  if (c.status == CancelResult::unknown) throw ApiError(404, "no job " + id);
  auto s = sched_.job(id);
  if (c.status == CancelResult::already_ended)
    throw ApiError(409, "job " + id + " already ended (" + to_string(s->state) + ")");
  drop_image(id);
  if (const auto page = sched_.frames(id, std::nullopt, 0))
    for (const protocol::JobStatus& f : page->frames) {
      drop_image(f.id);
      events_.job(f);
    }
  spdlog::info("job {}: cancelled, {} lease(s) revoked", id, c.revoked_leases);
  events_.job(*s);
  return std::move(*s);
}

protocol::JobStatus JobService::retry(const std::string& id, const std::vector<int64_t>& frames) {
  refuse_frame(id, "retry");
  if (!frames.empty() && !status(id).frames)
    throw ApiError(400, "job " + id + " is not a sequence: a retry of it names no frames");
  const RetryResult r = sched_.retry(id, frames);
  switch (r.status) {
    case RetryResult::unknown: throw ApiError(404, "no job " + id);
    case RetryResult::no_frame:
      throw ApiError(404, "job " + id + " has no frame " + std::to_string(r.frame));
    case RetryResult::not_ended:
      if (status(id).frames)
        throw ApiError(409, "job " + id + " is " + to_string(r.was) + ": none of " +
                                (frames.empty() ? std::string("its frames") : "the chosen frames") +
                                " failed or was cancelled");
      throw ApiError(409, "job " + id + " is " + to_string(r.was) + ": only failed or cancelled jobs can be retried");
    case RetryResult::done: throw ApiError(409, "job " + id + " is done: only failed or cancelled jobs can be retried");
    case RetryResult::retried: break;
  }
  spdlog::info("job {}: retried after it was {}; {} tile(s) to render, done tiles kept{}", id, to_string(r.was),
               r.pending, r.jobs.size() > 1 || r.jobs.front() != id ? " (" + std::to_string(r.jobs.size()) + " frames)" : "");
  for (const std::string& job : r.jobs) {
    if (job != id) announce(job);
    const auto j = sched_.job(job);
    if (j && j->tiles.pending == 0 && !j->tiles.leased) finalize(job);  // every tile was done: only the result is missing
  }
  announce(id);
  return status(id);
}

protocol::JobStatus JobService::pause(const std::string& id) {
  refuse_frame(id, "pause");
  const PauseResult r = sched_.pause(id);
  if (r.status == PauseResult::unknown) throw ApiError(404, "no job " + id);
  if (r.status == PauseResult::wrong_state)
    throw ApiError(409, "job " + id + " is " + to_string(r.was) + ": only queued or running jobs can be paused");
  spdlog::info("job {}: paused (was {})", id, to_string(r.was));
  announce_frames(id);
  return announce(id);
}

protocol::JobStatus JobService::resume(const std::string& id) {
  refuse_frame(id, "resume");
  const PauseResult r = sched_.resume(id);
  if (r.status == PauseResult::unknown) throw ApiError(404, "no job " + id);
  if (r.status == PauseResult::wrong_state)
    throw ApiError(409, "job " + id + " is " + to_string(r.was) + ": only paused jobs can be resumed");
  spdlog::info("job {}: resumed", id);
  announce_frames(id);
  return announce(id);
}

protocol::JobStatus JobService::set_priority(const std::string& id, int priority) {
  refuse_frame(id, "change the priority of");
  const PriorityResult r = sched_.set_priority(id, priority);
  if (r.status == PriorityResult::unknown) throw ApiError(404, "no job " + id);
  if (r.status == PriorityResult::ended)
    throw ApiError(409, "job " + id + " is " + to_string(r.was) + ": only a job that has not ended can change priority");
  spdlog::info("job {}: priority {}", id, priority);
  announce_frames(id);
  return announce(id);
}

protocol::JobSpec JobService::spec(const std::string& id) {
  {
    std::lock_guard lock(mu_);
    const auto it = specs_.find(id);
    if (it != specs_.end()) return it->second;
  }
  const auto job = sched_.job(id);
  if (!job) throw ApiError(404, "no job " + id);
  if (job->frames)
    throw ApiError(409, "job " + id + " is a sequence: each frame has its own spec (GET " +
                            protocol::routes::job_spec(frame_job_id(id, job->frames->first)) + ")");
  std::optional<json> rec = jobs_.load_record(id);
  if (!rec) throw ApiError(404, "no record for job " + id);
  const auto spec = rec->get<protocol::JobSpec>();  // records of older versions also carry the job's facts: ignored
  std::lock_guard lock(mu_);
  cache_spec_locked(id, spec, false);  // a newer spec cached meanwhile (a raise) stays
  return spec;
}

std::string JobService::spec_json(const std::string& id) {
  {
    std::lock_guard lock(mu_);
    const auto it = spec_json_.find(id);
    if (it != spec_json_.end()) return it->second;
  }
  spec(id);  // loads the record and caches both forms
  std::lock_guard lock(mu_);
  const auto it = spec_json_.find(id);
  if (it == spec_json_.end()) throw ApiError(404, "no job " + id);  // purged meanwhile
  return it->second;
}

void JobService::cache_spec_locked(const std::string& id, const protocol::JobSpec& spec, bool replace) {
  if (!replace && specs_.count(id)) return;
  specs_[id] = spec;
  spec_json_[id] = json(spec).dump();
}

std::filesystem::path JobService::result_exr(const std::string& id) {
  const protocol::JobStatus s = status(id);
  if (s.frames)
    throw ApiError(409, "job " + id + " is a sequence: each frame has its own result (GET " +
                            protocol::routes::job_frame_result(id, s.frames->first) + ")");
  if (s.state != JobState::done) throw ApiError(409, "job " + id + " is " + to_string(s.state) + ", not done");
  return jobs_.result_path(id);
}

std::vector<uint8_t> JobService::preview_png(const std::string& id, std::optional<Layer> layer) {
  protocol::JobStatus s = status(id);
  if (layer && !s.frames && !job_layers(id).has(*layer))
    throw ApiError(404, "job " + id + " has no layer " + std::string(enum_name(*layer, kLayerNames)));
  if (s.frames) {
    // A sequence shows its latest frame with pixels: the last done one, else the first started, else the first.
    const FramePage page = *sched_.frames(id, std::nullopt, 0);
    const protocol::JobStatus* shown = &page.frames.front();
    for (const protocol::JobStatus& f : page.frames)
      if (f.state == JobState::done || (shown->state != JobState::done && f.started_ms && !shown->started_ms))
        shown = &f;
    return preview_png(shown->id, layer);
  }
  const int width = s.params.width, height = s.params.height;
  // The version of the pixels a preview shows: a job's image in memory changes its generation with every tile pasted;
  // a done job's result changes only when a raised spp is done (failed and cancelled jobs show black).
  std::shared_ptr<JobImage> image;
  std::string version;
  if (!is_final(s.state)) {
    image = image_for(id, width, height);
    version = "tiles " + std::to_string(image->generation());  // read before the preview is made from the image
  } else {
    version = s.state == JobState::done ? "done " + std::to_string(s.params.spp) : "black";
  }
  if (layer) {
    version += " " + std::string(enum_name(*layer, kLayerNames));
    if (const Png kept = previews_.find(id, version)) return *kept;
    std::vector<uint8_t> bytes;
    if (image) {
      bytes = image->layer_preview_png(*layer);
    } else if (s.state == JobState::done) {
      const Image shown = layer_display(read_exr(jobs_.result_path(id)).pixels, *layer);
      bytes = server::preview_png(&shown, width, height);
    } else {
      bytes = server::preview_png(nullptr, width, height);
    }
    Png png = std::make_shared<const std::vector<uint8_t>>(std::move(bytes));
    previews_.put(id, version, png);
    return *png;
  }
  if (const Png kept = previews_.find(id, version)) return *kept;
  Png png = std::make_shared<const std::vector<uint8_t>>(
      image                          ? image->preview_png()
      : s.state == JobState::done ? preview_png_of_exr(jobs_.result_path(id), width, height)  // a few rows at a time
                                  : server::preview_png(nullptr, width, height));
  previews_.put(id, version, png);
  return *png;
}

std::shared_ptr<JobImage> JobService::image_for(const std::string& job, int width, int height) {
  const std::vector<std::string> layers = layer_channels(job_layers(job));
  std::lock_guard lock(mu_);
  auto& slot = images_[job];
  if (!slot) {
    // First use since the coordinator started: the done tiles are in the store. Holding the lock while reading them
    // means an upload finishing meanwhile either is among them or pastes into this image afterwards.
    auto img = std::make_shared<JobImage>(width, height, layers);
    const auto s = sched_.job(job);
    if (s) {
      const TileGrid grid(s->params.width, s->params.height, s->params.tile_size);
      for (const auto& [index, bytes] : jobs_.tile_pixels(job)) {
        const PixelWindow w = grid.window(index);
        img->paste(tile_from_bytes(bytes, w.width(), w.height(), layers), w);
      }
    }
    slot = std::move(img);
  }
  return slot;
}

void JobService::prepare_image(const std::string& job) {
  results_([this, job] {
    const auto s = sched_.job(job);
    if (!s || is_final(s->state)) return;
    image_for(job, s->params.width, s->params.height)->allocate();
    // Ended meanwhile (its image dropped before this one was made): not kept.
    if (const auto now = sched_.job(job); !now || is_final(now->state)) drop_image(job);
  });
}

void JobService::drop_image(const std::string& job) {
  std::lock_guard lock(mu_);
  images_.erase(job);
  previews_.erase(job);
}

void JobService::after_failure(const ResultClaim& tile, const std::string& error, const FailResult& f) {
  events_.tile(protocol::events::kTileFailed, {tile.job, tile.tile, tile.worker, std::nullopt, error});
  if (!f.job_failed) return;
  drop_image(tile.job);
  announce(tile.job);
}

void JobService::announce_frames(const std::string& job) {
  if (const auto page = sched_.frames(job, std::nullopt, 0))
    for (const protocol::JobStatus& f : page->frames) events_.job(f);
}

protocol::JobStatus JobService::announce(const std::string& job) {
  protocol::JobStatus s = status(job);
  events_.job(s);
  if (s.sequence)  // a frame's change is its sequence's too
    if (const auto seq = sched_.job(*s.sequence)) events_.job(*seq);
  return s;
}

UploadOutcome JobService::accept_tile(const std::string& lease, std::string_view exr, uint64_t rays,
                                      std::vector<std::string> log) {
  std::promise<UploadOutcome> answer;
  std::future<UploadOutcome> answered = answer.get_future();
  accept_tile(lease, exr, rays, std::move(log), [&answer](UploadOutcome o, std::exception_ptr error) {
    if (error) answer.set_exception(error);
    else answer.set_value(o);
  });
  return answered.get();
}

void JobService::accept_tile(const std::string& lease, std::string_view exr, uint64_t rays, std::vector<std::string> log,
                             UploadDone done, const std::function<void()>& stored) {
  // A settled upload's answer: a duplicate only once what it duplicates is on the disk (its merge may have been
  // committed a moment ago, and the uploader stops retrying on this answer).
  auto settled = [&](const ResultClaim& c) -> bool {
    switch (c.status) {
      case ResultClaim::unknown: throw ApiError(404, "unknown lease " + lease);
      case ResultClaim::discarded:
        spdlog::info("job {} tile {} worker {}: result discarded (job ended)", c.job, c.tile, c.worker);
        done(UploadOutcome::discarded, nullptr);
        return true;
      case ResultClaim::duplicate:
        spdlog::info("job {} tile {} worker {}: duplicate result acknowledged", c.job, c.tile, c.worker);
        sched_.after_sync([done] { done(UploadOutcome::duplicate, nullptr); });
        return true;
      case ResultClaim::proceed: break;
    }
    return false;
  };
  try {
    const ResultClaim pre = sched_.check_result(lease);
    if (settled(pre)) return;

    // Validated outside every lock, decoded from memory.
    const std::vector<std::string> layers = layer_channels(job_layers(pre.job));
    TileCheck check = check_tile_exr(exr, pre.window, pre.width, pre.height, layers);
    // A resumable job's tile must carry its exact sums at the job's spp (server/tile_state.h).
    const std::optional<protocol::SamplingSettings> sampling = resumable_sampling(pre.job);
    if (!check.error && sampling) check.error = check_tile_state(check.pixels, pre.spp, sampling->replicates);
    if (check.error) {
      const FailResult f = sched_.fail(lease, "invalid result: " + *check.error);
      spdlog::warn("job {} tile {} worker {}: invalid result: {}{}", pre.job, pre.tile, pre.worker, *check.error,
                   f.job_failed ? " (job failed)" : f.blocklisted ? " (worker blocklisted for the job)" : "");
      after_failure(pre, "invalid result: " + *check.error, f);
      throw ApiError(422, "invalid result: " + *check.error);
    }

    const ResultClaim c = sched_.claim_result(lease);
    if (settled(c)) return;
    try {
      // Stored as uploaded, to continue from when the job's spp is raised (while the tile is claimed: no raise comes
      // between, and a lease of another spp was discarded by the claim).
      if (sampling) jobs_.save_tile_state(c.job, c.tile, c.spp, exr);
      // Pasted before the tile counts as done: the upload that finishes the job writes the image, and every other
      // tile's pixels must be in it by then (pasting identical pixels twice is harmless if the store then fails).
      image_for(c.job, c.width, c.height)->paste(check.pixels, c.window);  // after a restart, rebuilt from the store first
      // Durable before acknowledged: the pixels and the tile's done state go to the store in one transaction, and the
      // answer waits for the flush that covers it.
      std::string layered;  // the stored bytes of a tile with layers
      sched_.finish_result(lease, rays, tile_bytes(check.pixels, layers, layered), std::move(log),
                           [this, c, rays, done](FinishResult r) noexcept {
        metrics_.add_rays(rays, clock_());
        spdlog::info("job {} tile {} worker {}: merged", c.job, c.tile, c.worker);
        events_.tile(protocol::events::kTileDone, {c.job, c.tile, c.worker, std::nullopt, std::nullopt});
        if (!r.last) return done(UploadOutcome::accepted, nullptr);
        results_([this, job = c.job, done] {
          finalize(job);
          done(UploadOutcome::accepted, nullptr);
        });
      });
    } catch (...) {
      sched_.abandon_result(lease);
      throw;
    }
  } catch (...) {
    done(UploadOutcome::accepted, std::current_exception());
    return;
  }
  if (stored) stored();
}

void JobService::record_failure(const std::string& lease, const protocol::FailReport& report) {
  const ResultClaim info = sched_.check_result(lease);
  const FailResult f = sched_.fail(lease, report.error, report.log);
  if (f.status == FailResult::unknown) throw ApiError(404, "unknown lease " + lease);
  spdlog::warn("job {} tile {} worker {}: failed: {}{}", info.job, info.tile, info.worker, report.error,
               f.job_failed ? " (job failed)" : f.blocklisted ? " (worker blocklisted for the job)" : "");
  after_failure(info, report.error, f);
}

protocol::TileList JobService::tiles(const std::string& id) {
  auto t = sched_.tiles(id);
  if (!t) throw ApiError(404, "no job " + id);
  if (const auto s = sched_.job(id); s && s->frames)
    throw ApiError(409, "job " + id + " is a sequence: its tiles are its frames' (GET " + protocol::routes::job_frames(id) +
                            " lists the frames' jobs)");
  return std::move(*t);
}

protocol::TileInfo JobService::requeue_tile(const std::string& id, const std::string& tile) {
  if (const auto s = sched_.job(id); s && s->frames)
    throw ApiError(409, "job " + id + " is a sequence: its tiles are its frames' (requeue a tile of a frame's job, e.g. " +
                            frame_job_id(id, s->frames->first) + ")");
  int64_t n = -1;
  const auto [end, ec] = std::from_chars(tile.data(), tile.data() + tile.size(), n);
  if (ec != std::errc() || end != tile.data() + tile.size()) n = -1;
  const RequeueResult r = sched_.requeue(id, n);
  switch (r.status) {
    case RequeueResult::unknown: throw ApiError(404, "no job " + id);
    case RequeueResult::no_tile:
      throw ApiError(404, "job " + id + " has no tile '" + tile + "' (its tiles are 0.." + std::to_string(r.tiles - 1) + ")");
    case RequeueResult::wrong_job_state:
      throw ApiError(409, "job " + id + " is " + to_string(r.job_state) +
                              (r.job_state == JobState::queued ? ": none of its tiles has been rendered yet"
                               : r.job_state == JobState::done ? ": its result is written; submit it again to re-render"
                                                               : ": retry it first"));
    case RequeueResult::wrong_tile_state:
      throw ApiError(409, "tile " + tile + " of job " + id +
                              (r.was == TileState::merging ? " is being merged; requeue it when it is done"
                                                           : " is pending already and has not failed"));
    case RequeueResult::requeued: break;
  }
  spdlog::info("job {} tile {}: requeued (was {}{})", id, n, to_string(r.was), r.revoked ? ", lease revoked" : "");
  events_.tile(protocol::events::kTileRequeued, {id, n, "", std::nullopt, std::nullopt});
  return tiles(id).tiles.at(size_t(n));
}

void JobService::recover() {
  for (const std::string& job : sched_.unfinalized_jobs()) {
    spdlog::info("job {}: every tile was done before the restart; writing the result", job);
    finalize(job);
  }
  for (const std::string& job : jobs_.jobs_with_outputs()) {
    if (sched_.job(job)) continue;
    spdlog::info("job {}: purged before the restart; deleting its result", job);
    jobs_.remove_outputs(job);
  }
}

bool JobService::write_waiting_results() {
  std::set<std::string> jobs;
  {
    std::lock_guard lock(mu_);
    jobs.swap(waiting_results_);
  }
  for (const std::string& job : jobs) {
    const auto s = sched_.job(job);
    if (!s || !started_and_open(*s) || s->tiles.done != s->tiles.total) continue;  // purged or changed meanwhile
    spdlog::info("job {}: writing the result that waited for disk space", job);
    finalize(job);
  }
  std::lock_guard lock(mu_);
  return waiting_results_.empty();
}

protocol::JobState JobService::purge(const std::string& id) {
  refuse_frame(id, "purge");
  // A sequence's frames go with it (their ids, gathered before the scheduler forgets them).
  std::vector<std::string> gone{id};
  if (const auto page = sched_.frames(id, std::nullopt, 0))
    for (const protocol::JobStatus& f : page->frames) gone.push_back(f.id);
  const PurgeResult r = sched_.purge(id);
  switch (r.status) {
    case PurgeResult::unknown: throw ApiError(404, "no job " + id);
    case PurgeResult::not_ended:
      throw ApiError(409, "job " + id + " is " + to_string(r.was) +
                              ": only done, failed or cancelled jobs can be purged (cancel it first)");
    case PurgeResult::busy:
      throw ApiError(409, "job " + id + " is " + to_string(r.was) + " but an upload of one of its tiles is being stored; "
                              "purge it again in a moment");
    case PurgeResult::holds: {
      std::string held;
      for (const std::string& h : r.held) held += (held.empty() ? "" : ", ") + h;
      throw ApiError(409, "job " + id + " holds back " + held + " (waiting for it or blocked by it); cancel " +
                              (r.held.size() > 1 ? "them" : "it") + " first");
    }
    case PurgeResult::purged: break;
  }
  for (const std::string& job : gone) {
    {
      std::lock_guard lock(mu_);
      images_.erase(job);
      specs_.erase(job);
      spec_json_.erase(job);
    }
    previews_.erase(job);
    // The rows are gone (a restart deletes the file if this fails: see recover).
    jobs_.remove_outputs(job);
  }
  spdlog::info("job {}: purged (was {})", id, to_string(r.was));
  events_.job_removed({id, r.was});
  return r.was;
}

std::map<std::string, std::string> JobService::spec_assets(const std::string& id) {
  {
    std::lock_guard lock(mu_);
    if (const auto it = specs_.find(id); it != specs_.end()) return it->second.assets;
  }
  const std::optional<json> rec = jobs_.load_record(id);
  if (!rec) throw ApiError(404, "no record for job " + id);
  return rec->get<protocol::JobSpec>().assets;
}

std::set<std::string> JobService::referenced_blobs() {
  std::set<std::string> out;
  for (const protocol::JobStatus& top : sched_.jobs()) {
    std::vector<std::string> ids{top.id};  // a sequence's specs are its frames'
    if (top.frames)
      if (const auto page = sched_.frames(top.id, std::nullopt, 0)) {
        ids.clear();
        for (const protocol::JobStatus& f : page->frames) ids.push_back(f.id);
      }
    for (const std::string& id : ids) {
      try {
        for (const auto& [path, sha] : spec_assets(id)) out.insert(sha);
      } catch (const ApiError&) {
        if (sched_.job(id)) throw;  // a job without a readable spec: collect nothing rather than its blobs
      }
    }
  }
  return out;
}

void JobService::finalize(const std::string& job) {
  const auto s = sched_.job(job);
  if (!s) return;
  const auto img = image_for(job, s->params.width, s->params.height);
  const auto t0 = std::chrono::steady_clock::now();
  const int64_t now = clock_();
  // The sampling settings are recorded as `tessera render` records them (adaptive jobs: "adaptive" and its options);
  // a job whose record is missing is recorded by the spp and seed the scheduler holds.
  protocol::SamplingSettings sampling;
  sampling.spp = s->params.spp;
  sampling.seed = s->params.seed;
  std::map<std::string, std::string> meta;
  try {
    const protocol::JobSpec sp = spec(job);
    sampling = sp.sampling;
    // Cryptomatte's manifests name the scene's materials and objects: the scene is read again (not built) for them.
    if (sampling.layers.has(Layer::kCryptoMaterial) || sampling.layers.has(Layer::kCryptoObject)) {
      try {
        meta = check_scene(sp.scene, sp.assets, sampling, "").layer_metadata;
      } catch (const std::exception& e) {
        spdlog::warn("job {}: no Cryptomatte manifest in the result: {}", job, e.what());
      }
    }
  } catch (const ApiError&) {
  }
  sampling.spp = s->params.spp;
  const bool resumable = resumable_sampling(job).has_value();
  meta.merge(sampling.metadata());
  meta.insert({
      {"tessera:version", TESSERA_VERSION},
      {"tessera:job", job},
      {"tessera:name", s->params.name},
      {"tessera:sceneHash", s->params.scene_hash},
      {"tessera:tileSize", std::to_string(s->params.tile_size)},
      {"tessera:workers", join_workers(s->workers)},
      {"tessera:createdMs", std::to_string(s->created_ms)},
      {"tessera:startedMs", std::to_string(s->started_ms.value_or(0))},
      {"tessera:finishedMs", std::to_string(now)},
      {"tessera:renderSeconds", std::to_string(double(now - s->started_ms.value_or(now)) / 1000.0)}});
  if (s->sequence) {
    meta["tessera:sequence"] = *s->sequence;
    meta["tessera:frame"] = std::to_string(*s->frame);
  }
  try {
    std::map<std::string, std::vector<uint32_t>> state;  // a resumable job's result can be refined like its tiles
    if (resumable)
      state = result_state_channels(jobs_, job, TileGrid(s->params.width, s->params.height, s->params.tile_size),
                                    sampling.spp, sampling.replicates);
    jobs_.write_result(job, [&](const fs::path& file) { img->write_exr(file, meta, state); });
  } catch (const std::exception& e) {
    // The EXR writer does not say why a write failed: a disk with less room than the pixels take is taken to be it.
    const uint64_t pixel_bytes = uint64_t(s->params.width) * uint64_t(s->params.height) * 12;
    if (is_disk_full(e) || disk_.free_bytes() < pixel_bytes) {
      disk_.note_full("writing the result of job " + job + ": " + e.what());
      spdlog::warn("job {}: its result does not fit on the disk; its tiles are kept and the result is written once "
                   "space is freed", job);
      std::lock_guard lock(mu_);
      waiting_results_.insert(job);
      return;
    }
    spdlog::error("job {}: writing the result failed: {}", job, e.what());
    sched_.fail_job(job, std::string("writing the result failed: ") + e.what());
    drop_image(job);
    announce(job);
    return;
  }
  try {
    sched_.complete_job(job);
  } catch (const std::exception& e) {
    // Done in the scheduler all the same; the change is stored with the next write that the disk takes (a restart
    // before it finds the job with every tile done and writes the result again).
    if (!is_disk_full(e)) throw;
    disk_.note_full(e.what());
  }
  drop_image(job);
  const protocol::JobStatus done = announce(job);
  if (done.sequence) events_.frame_done({*done.sequence, *done.frame, job});
  if (steps_) steps_->job_done(job);
  spdlog::info("job {}: done, result written in {:.3f}s", job,
               std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count());
}

}  // namespace tessera::server
