#include "client/job_client.h"

#include "core/util/file_io.h"
#include "core/scene/scene_loader.h"
#include "core/util/sha256.h"
#include "protocol/events.h"
#include "protocol/query.h"
#include "protocol/routes.h"
#include "client/backoff.h"
#include "client/sse_parser.h"

#include <nlohmann/json.hpp>
#include <spdlog/spdlog.h>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <map>
#include <mutex>
#include <optional>
#include <set>
#include <thread>
#include <vector>

namespace tessera::client {

namespace fs = std::filesystem;
namespace routes = protocol::routes;
using nlohmann::json;

namespace {

// A file the submission needs, or SubmitError saying why not.
std::string read_file(const fs::path& path) {
  try {
    return read_file_bytes(path);
  } catch (const FileError& e) {
    throw SubmitError(e.what());
  }
}

[[noreturn]] void refuse(const std::string& what, const HttpResponse& r) {
  throw SubmitError(what + ": the coordinator answered " + std::to_string(r.status) + ": " + r.error_text());
}

// GET target, its 200 answer read as a T (`what` names it in errors).
template <class T>
T get_answer(HttpClient& http, const std::string& target, const std::string& what) {
  const HttpResponse r = http.send("GET", target);
  if (r.status != 200) refuse("GET " + target, r);
  return protocol::parse_answer<T>(r.body, what);
}

}  // namespace

namespace {

// What reading a sequence's frames learns once for all of them: each (folder, asset path)'s file, each file's hash.
struct AssetMemo {
  std::mutex mu;  // frames are read on several threads
  std::map<std::pair<fs::path, std::string>, fs::path> files;
  std::map<fs::path, std::string> hashes;
};

// Reads one scene file and hashes its assets (each file resolved and hashed once, through `memo`).
void read_scene_file(const SubmitOptions& o, const fs::path& scene, const std::string& where, json& out_scene,
                     std::vector<LocalAsset>& out_assets, AssetMemo& memo) {
  try {
    out_scene = json::parse(read_file(scene));
  } catch (const json::parse_error& e) {
    throw SceneError(where + scene.string() + ": not valid JSON: " + e.what());
  } catch (const SubmitError& e) {
    throw SubmitError(where + e.what());
  }
  const fs::path base = scene.has_parent_path() ? scene.parent_path() : fs::path(".");
  const fs::path root = o.asset_root ? *o.asset_root : base;
  const std::vector<std::string> paths = scene_asset_paths(out_scene);
  std::lock_guard lock(memo.mu);
  for (const std::string& rel : paths) {
    auto known = memo.files.find({base, rel});
    if (known == memo.files.end()) {
      try {
        known = memo.files.emplace(std::pair{base, rel}, resolve_inside(base, root, rel, "asset '" + rel + "'")).first;
      } catch (const SceneError& e) {
        throw SceneError(where + e.what());
      }
    }
    const fs::path& file = known->second;
    auto it = memo.hashes.find(file);
    if (it == memo.hashes.end()) it = memo.hashes.emplace(file, sha256_file(file)).first;
    out_assets.push_back(LocalAsset{rel, file, it->second});
  }
}

}  // namespace

SceneFiles read_scene_files(const SubmitOptions& o) {
  SceneFiles out;
  AssetMemo hashed;
  if (o.frames.empty()) {
    read_scene_file(o, o.scene, "", out.scene, out.assets, hashed);
    return out;
  }
  // Read and parsed on every core; the error reported is the lowest-numbered frame's, whatever the order.
  out.frames.resize(o.frames.size());
  std::vector<std::exception_ptr> failed(o.frames.size());
  tbb::parallel_for(tbb::blocked_range<size_t>(0, o.frames.size()), [&](const tbb::blocked_range<size_t>& r) {
    for (size_t i = r.begin(); i != r.end(); ++i) {
      const FrameScene& f = o.frames[i];
      FrameFiles& ff = out.frames[i];
      ff.number = f.number;
      try {
        read_scene_file(o, f.scene, "frame " + std::to_string(f.number) + ": ", ff.scene, ff.assets, hashed);
      } catch (...) {
        failed[i] = std::current_exception();
      }
    }
  });
  for (const std::exception_ptr& e : failed)
    if (e) std::rethrow_exception(e);
  return out;
}

SubmitResult submit_job(HttpClient& http, const SubmitOptions& o) { return submit_job(http, o, read_scene_files(o)); }

namespace {

// The blobs among `hashes` that the coordinator does not hold, asked in one request per kMaxBlobQuery (each one held
// starts its grace period again); nothing when the coordinator predates POST /v1/blobs (404 or 405).
std::optional<std::set<std::string>> missing_blobs(HttpClient& http, const std::vector<std::string>& hashes) {
  std::set<std::string> missing;
  for (size_t i = 0; i < hashes.size(); i += protocol::kMaxBlobQuery) {
    protocol::BlobQuery q;
    q.sha256.assign(hashes.begin() + i, hashes.begin() + std::min(hashes.size(), i + protocol::kMaxBlobQuery));
    const HttpResponse r = http.send("POST", routes::blobs(), json(q).dump());
    if (r.status == 404 || r.status == 405) return std::nullopt;
    if (r.status != 200) refuse("POST " + routes::blobs() + " (which assets to upload)", r);
    for (std::string& h : protocol::parse_answer<protocol::BlobQueryAnswer>(r.body, "blob query").missing)
      missing.insert(std::move(h));
  }
  return missing;
}

}  // namespace

protocol::JobSubmission job_submission(const SubmitOptions& o, SceneFiles files) {
  protocol::JobSubmission job;
  for (const LocalAsset& a : files.assets) job.assets[a.path] = a.sha256;
  job.scene = std::move(files.scene);
  if (!files.frames.empty()) {
    // The frames' assets go once, in "assets", unless one path names different files in different frames: then
    // every frame carries its own.
    bool shared = true;
    for (const FrameFiles& f : files.frames)
      for (const LocalAsset& a : f.assets) shared = job.assets.emplace(a.path, a.sha256).first->second == a.sha256 && shared;
    if (!shared) job.assets.clear();
    for (FrameFiles& f : files.frames) {
      protocol::FrameSubmission fs{f.number, std::move(f.scene), {}};
      if (!shared)
        for (const LocalAsset& a : f.assets) fs.assets[a.path] = a.sha256;
      job.frames.push_back(std::move(fs));
    }
    job.frame_order = o.frame_order;
  }
  job.sampling = o.sampling;
  job.tile_size = o.tile_size;
  job.priority = o.priority;
  job.tile_timeout_seconds = o.tile_timeout_seconds;
  job.name = !o.name.empty()       ? o.name
             : o.frames.empty() ? o.scene.filename().string()
                                : o.frames.front().scene.filename().string() + " .. " +
                                      o.frames.back().scene.filename().string();
  job.resumable = o.resumable;
  job.require = o.require;
  job.max_workers = o.max_workers;
  job.pipeline = o.pipeline;
  return job;
}

SubmitResult submit_job(HttpClient& http, const SubmitOptions& o, SceneFiles files) {
  SubmitResult out;
  // Every distinct asset, once (a sequence's frames share most of theirs).
  std::vector<const LocalAsset*> assets;
  std::set<std::string> distinct;
  for (const LocalAsset& a : files.assets)
    if (distinct.insert(a.sha256).second) assets.push_back(&a);
  for (const FrameFiles& f : files.frames)
    for (const LocalAsset& a : f.assets)
      if (distinct.insert(a.sha256).second) assets.push_back(&a);
  std::vector<std::string> hashes(distinct.begin(), distinct.end());
  out.assets_total = int(assets.size());
  // One question for every asset, then only the missing ones are sent (a coordinator without the question: one HEAD
  // per asset, as before).
  const std::optional<std::set<std::string>> missing = missing_blobs(http, hashes);
  std::set<std::string> sent;
  for (const LocalAsset* ap : assets) {
    const LocalAsset& a = *ap;
    const std::string& hash = a.sha256;
    if (sent.count(hash)) continue;  // the same file named twice
    if (missing) {
      if (!missing->count(hash)) continue;
    } else {
      const HttpResponse head = http.send("HEAD", routes::blob(hash));
      if (head.status == 200) continue;
      if (head.status != 404) refuse("HEAD " + routes::blob(hash) + " (" + a.path + ")", head);
    }
    const HttpResponse put = http.send("PUT", routes::blob(hash), read_file(a.file), "application/octet-stream");
    if (put.status != 201 && put.status != 200) refuse("uploading " + a.path, put);
    sent.insert(hash);
    ++out.assets_uploaded;
  }
  const protocol::JobSubmission job = job_submission(o, std::move(files));
  const std::string body = json(job).dump();
  HttpResponse r = http.send("POST", routes::jobs(), body);
  // 503: every place of the coordinator's admission pool is taken (--max-validations, --validation-queue); nothing was
  // stored, so the same submission goes again after Retry-After, drawn from [Retry-After, 2 x Retry-After] so that
  // many clients turned away together spread out.
  for (bool told = false; r.status == 503; told = true) {
    int seconds = 1;
    try {
      seconds = std::clamp(std::stoi(r.header("retry-after")), 1, 60);
    } catch (const std::exception&) {
    }
    if (!told) spdlog::info("the coordinator is busy checking other submissions; retrying {} in about {} s", o.scene.string(), seconds);
    std::this_thread::sleep_for(Backoff(std::chrono::seconds(2 * seconds), std::chrono::seconds(2 * seconds)).next());
    r = http.send("POST", routes::jobs(), body);
  }
  if (r.status != 201 && r.status != 200)
    refuse("submitting " + (o.frames.empty() ? o.scene.string() : job.name), r);
  out.job_id = protocol::parse_answer<protocol::SubmitAnswer>(r.body, "job submission").id;
  return out;
}

JobStatus get_job(HttpClient& http, const std::string& id) {
  return get_answer<JobStatus>(http, routes::job(id), "job " + id);
}

protocol::JobSpec get_job_spec(HttpClient& http, const std::string& id) {
  return get_answer<protocol::JobSpec>(http, routes::job_spec(id), "spec of job " + id);
}

std::vector<JobStatus> list_jobs(HttpClient& http) {
  return get_answer<protocol::JobList>(http, routes::jobs(), "job list").jobs;
}

protocol::JobList list_jobs(HttpClient& http, const protocol::JobListQuery& query) {
  return get_answer<protocol::JobList>(http, routes::jobs() + query.to_query(), "job list");
}

protocol::Me whoami(HttpClient& http) { return get_answer<protocol::Me>(http, routes::me(), "who am I"); }

protocol::AuditList list_audit(HttpClient& http, const protocol::AuditQuery& query) {
  return get_answer<protocol::AuditList>(http, routes::audit() + query.to_query(), "audit trail");
}

protocol::TileList get_job_tiles(HttpClient& http, const std::string& id) {
  return get_answer<protocol::TileList>(http, routes::job_tiles(id), "tiles of job " + id);
}

namespace {
// A request that changes a job or a worker; the answer is it as it is now.
template <class T = JobStatus>
T control(HttpClient& http, const std::string& id, const char* method, const std::string& path, const char* doing,
          std::string body = {}) {
  const HttpResponse r = http.send(method, path, std::move(body));
  if (r.status != 200) refuse(std::string(doing) + " " + id, r);
  return protocol::parse_answer<T>(r.body, id);
}
}  // namespace

std::vector<protocol::WorkerInfo> list_workers(HttpClient& http) {
  const HttpResponse r = http.send("GET", routes::workers());
  if (r.status != 200) refuse("GET " + routes::workers(), r);
  return protocol::parse_answer<protocol::WorkerList>(r.body, "worker list").workers;
}

protocol::TileInfo requeue_tile(HttpClient& http, const std::string& id, int64_t tile) {
  return control<protocol::TileInfo>(http, id + " tile " + std::to_string(tile), "POST", routes::job_tile_requeue(id, tile),
                                     "requeueing");
}

protocol::WorkerInfo drain_worker(HttpClient& http, const std::string& id, bool drain) {
  return control<protocol::WorkerInfo>(http, id, "POST", drain ? routes::worker_drain(id) : routes::worker_undrain(id),
                                       drain ? "draining" : "undraining");
}

protocol::FrameList list_frames(HttpClient& http, const std::string& id, const protocol::FrameListQuery& query) {
  return get_answer<protocol::FrameList>(http, routes::job_frames(id) + query.to_query(), "frames of job " + id);
}

JobStatus retry_job(HttpClient& http, const std::string& id, const std::vector<int64_t>& frames) {
  return control(http, id, "POST", routes::job_retry(id), "retrying",
                 frames.empty() ? std::string() : json(protocol::RetryRequest{frames}).dump());
}

JobStatus pause_job(HttpClient& http, const std::string& id) {
  return control(http, id, "POST", routes::job_pause(id), "pausing");
}

JobStatus resume_job(HttpClient& http, const std::string& id) {
  return control(http, id, "POST", routes::job_resume(id), "resuming");
}

JobStatus set_job_priority(HttpClient& http, const std::string& id, int priority) {
  return control(http, id, "PATCH", routes::job(id), "changing the priority of",
                     json(protocol::JobPatch{priority, std::nullopt}).dump());
}

JobStatus raise_job_spp(HttpClient& http, const std::string& id, uint32_t spp) {
  return control(http, id, "PATCH", routes::job(id), "raising the spp of", json(protocol::JobPatch{std::nullopt, spp}).dump());
}

namespace {

// Calls progress when the status differs from `last` in what a progress display shows; then it becomes `last`.
void report(const JobStatus& s, JobStatus& last, const std::function<void(const JobStatus&)>& progress) {
  if (progress && (s.tiles.done != last.tiles.done || s.state != last.state || s.tiles.total != last.tiles.total))
    progress(s);
  last = s;
}

// Follows the job on GET /v1/events: once the stream is open, its status (every later change arrives as an event),
// then its job events and a done tile count from tile_done events. Returns true when the job ended or stop() said
// so; false when the stream was refused or broke first (the caller polls).
bool follow_events(HttpClient& http, const std::string& id, const std::function<void(const JobStatus&)>& progress,
                   const std::function<bool()>& stop, JobStatus& last, bool tile_progress) {
  namespace ev = protocol::events;
  bool ended = false;
  SseParser parser([&](const SseMessage& m) {
    if (m.event == ev::kJob) {
      const JobStatus s = protocol::parse_answer<JobStatus>(m.data, "job event");
      if (s.id != id) return true;
      report(s, last, progress);
    } else if (m.event == ev::kTileDone) {
      if (protocol::parse_answer<protocol::TileEvent>(m.data, "tile event").job != id) return true;
      JobStatus s = last;
      s.tiles.done = std::min(s.tiles.total, s.tiles.done + 1);
      report(s, last, progress);
    } else if (m.event == ev::kResync) {
      report(get_job(http, id), last, progress);
    }
    ended = last.finished();
    return !ended;
  });
  HttpRequest req;
  req.target = routes::events() + (tile_progress ? "" : protocol::event_filter_query({ev::kJob}));
  req.headers["Accept"] = "text/event-stream";
  try {
    const HttpResponse r = http.another()->stream(req, std::chrono::seconds(60), [&](std::string_view bytes) {
      if (!bytes.empty()) return parser.feed(bytes);
      report(get_job(http, id), last, progress);  // the stream is open: from here on no change is missed
      ended = last.finished();
      return !ended;
    }, stop);
    if (r.status != 200) {
      spdlog::info("job {}: no event stream ({}: {}); polling", id, r.status, r.error_text());
      return false;
    }
  } catch (const TransportError& e) {
    spdlog::info("job {}: event stream unavailable ({}); polling", id, e.what());
    return false;
  } catch (const ProtocolError& e) {
    spdlog::warn("job {}: unreadable event ({}); polling", id, e.what());
    return false;
  }
  return ended || (stop && stop());
}

}  // namespace

JobStatus wait_for_job(HttpClient& http, const std::string& id, const std::function<void(const JobStatus&)>& progress,
                       const std::function<bool()>& stop, std::chrono::milliseconds poll, std::chrono::seconds give_up,
                       bool tile_progress) {
  JobStatus last;
  if (follow_events(http, id, progress, stop, last, tile_progress)) return last;
  Backoff backoff(poll, std::chrono::milliseconds(5000));
  auto failing_since = std::chrono::steady_clock::time_point{};
  while (true) {
    try {
      const JobStatus s = get_job(http, id);
      failing_since = {};
      backoff.reset();
      report(s, last, progress);
      if (s.finished()) return s;
      if (!sleep_unless(poll, stop)) return last;
    } catch (const TransportError& e) {
      const auto now = std::chrono::steady_clock::now();
      if (failing_since == std::chrono::steady_clock::time_point{}) {
        failing_since = now;
        spdlog::warn("job {}: coordinator unreachable ({}); retrying", id, e.what());
      } else if (now - failing_since > give_up) {
        throw;
      }
      if (!sleep_unless(backoff.next(), stop)) return last;
    }
  }
}

namespace {

// GETs `route` and writes its body to `path` whole (write_file_atomic); `what` names the download in a refusal.
uint64_t download_to(HttpClient& http, const std::string& route, const std::string& what, const fs::path& path) {
  const HttpResponse r = http.send("GET", route);
  if (r.status != 200) refuse("downloading " + what, r);
  try {
    write_file_atomic(path, r.body);
  } catch (const FileError& e) {
    throw SubmitError(e.what());
  }
  return r.body.size();
}

}  // namespace

uint64_t download_result(HttpClient& http, const std::string& id, const fs::path& path) {
  return download_to(http, routes::job_result(id), "the result of " + id, path);
}

uint64_t download_frame(HttpClient& http, const std::string& id, int64_t frame, const fs::path& path) {
  return download_to(http, routes::job_frame_result(id, frame), "frame " + std::to_string(frame) + " of " + id, path);
}

uint64_t download_output(HttpClient& http, const std::string& id, const std::string& name, const fs::path& path) {
  return download_to(http, routes::job_output(id, name), "output " + name + " of " + id, path);
}

protocol::PurgeAnswer purge_job(HttpClient& http, const std::string& id) {
  return control<protocol::PurgeAnswer>(http, id, "DELETE", routes::job_purge(id), "purging");
}

bool cancel_job(HttpClient& http, const std::string& id) {
  const HttpResponse r = http.send("DELETE", routes::job(id));
  if (r.status == 200) return true;
  if (r.status == 409) return false;
  refuse("cancelling " + id, r);
}

}  // namespace tessera::client
