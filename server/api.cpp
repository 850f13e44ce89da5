#include "server/api.h"

#include "core/scene_loader.h"
#include "core/sha256.h"
#include "core/tiles.h"

#include <spdlog/spdlog.h>

#include <algorithm>
#include <chrono>
#include <charconv>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <limits>
#include <set>

namespace fs = std::filesystem;
using nlohmann::json;

namespace tessera::server {

namespace {

using protocol::ApiError;
using protocol::ProtocolError;

// A refusal with this status and sentence.
ApiError refusal(http::status status, const std::string& what) { return ApiError(int(status), what); }

HttpResponse json_response(http::status status, const json& body, unsigned version) {
  HttpResponse res{status, version};
  res.set(http::field::content_type, "application/json");
  res.body() = body.dump();
  res.prepare_payload();
  return res;
}

HttpResponse bytes_response(std::string bytes, const char* content_type, unsigned version) {
  HttpResponse res{http::status::ok, version};
  res.set(http::field::content_type, content_type);
  res.body() = std::move(bytes);
  res.prepare_payload();
  return res;
}

std::string join_workers(const std::vector<std::string>& v) {
  std::string s;
  for (const auto& w : v) s += (s.empty() ? "" : ",") + w;
  return s;
}

}  // namespace

Route match_route(std::string_view target) {
  const protocol::RouteMatch m = protocol::match_route(target);
  Route r;
  if (!m.route) return r;
  r.id = m.route->endpoint;
  r.param = m.param;
  r.name = std::string(m.route->pattern);
  for (std::string_view v : m.route->methods) r.methods.push_back(http::string_to_verb(v));
  return r;
}

Access route_access(RouteId route, http::verb method) {
  switch (route) {
    case RouteId::healthz: return Access::open;
    case RouteId::metrics: return Access::either;
    case RouteId::blob: return method == http::verb::get ? Access::either : Access::client;  // HEAD/PUT: submitting
    case RouteId::job_spec: return Access::either;
    case RouteId::jobs:
    case RouteId::job:
    case RouteId::job_result:
    case RouteId::job_preview: return Access::client;
    case RouteId::workers:
    case RouteId::worker_lease:
    case RouteId::lease_heartbeat:
    case RouteId::lease_result:
    case RouteId::lease_fail:
    case RouteId::lease_release: return Access::worker;
    case RouteId::none: break;
  }
  return Access::client;  // unreachable for matched routes; the strictest answer otherwise
}

Api::Api(Scheduler& scheduler, BlobStore& blobs, JobStore& jobs, Metrics& metrics, ClockMs clock, ApiOptions options)
    : sched_(scheduler), blobs_(blobs), jobs_(jobs), metrics_(metrics), clock_(std::move(clock)), opt_(options) {}

std::size_t Api::body_limit(const http::request_header<>& h) {
  const Route r = match_route(h.target());
  if (r.id == RouteId::blob && h.method() == http::verb::put) return opt_.blob_limit;
  if (r.id == RouteId::lease_result && h.method() == http::verb::put) return opt_.result_limit;
  return opt_.json_limit;
}

std::optional<HttpResponse> Api::check_access(const Route& route, const http::request_header<>& h) {
  const AuthDecision d = authorize(route_access(route.id, h.method()), h[http::field::authorization], opt_.tokens);
  if (d.status == AuthDecision::allowed) return std::nullopt;
  const bool forbidden = d.status == AuthDecision::wrong_role;
  HttpResponse res = json_error(forbidden ? http::status::forbidden : http::status::unauthorized, d.reason, h.version());
  if (!forbidden)
    res.set(http::field::www_authenticate,
            d.status == AuthDecision::missing ? "Bearer realm=\"tessera\"" : "Bearer realm=\"tessera\", error=\"invalid_token\"");
  // The reason names roles, never the presented or configured token.
  spdlog::warn("{} {}: {} {}", std::string(h.method_string()), route.name, forbidden ? 403 : 401, d.reason);
  return res;
}

std::optional<HttpResponse> Api::early_response(const http::request_header<>& h) noexcept {
  try {
    const Route route = match_route(h.target());
    if (route.id == RouteId::none ||
        std::find(route.methods.begin(), route.methods.end(), h.method()) == route.methods.end())
      return std::nullopt;  // handle() answers 404/405 (after the body, which is small or refused by its limit)
    std::optional<HttpResponse> res = check_access(route, h);
    if (res) metrics_.observe_request(std::string(h.method_string()) + " " + route.name, 0.0);
    return res;
  } catch (...) {
    return json_error(http::status::internal_server_error, "internal error", h.version());
  }
}

HttpResponse Api::handle(HttpRequest&& req) noexcept {
  const auto t0 = std::chrono::steady_clock::now();
  const unsigned version = req.version();
  std::string label = "unmatched";
  HttpResponse res;
  try {
    try {
      const Route route = match_route(req.target());
      if (route.id == RouteId::none) {
        res = json_error(http::status::not_found, "no such endpoint: " + std::string(req.target()), version);
      } else {
        label = std::string(req.method_string()) + " " + route.name;
        if (std::find(route.methods.begin(), route.methods.end(), req.method()) == route.methods.end()) {
          std::string allow;
          for (http::verb v : route.methods) allow += (allow.empty() ? "" : ", ") + std::string(http::to_string(v));
          label = "other " + route.name;
          res = json_error(http::status::method_not_allowed,
                           std::string(req.method_string()) + " is not allowed on " + route.name + " (allowed: " + allow + ")", version);
          res.set(http::field::allow, allow);
        } else if (auto denied = check_access(route, req.base())) {
          res = std::move(*denied);
        } else {
          res = dispatch(route, req);
        }
      }
    } catch (const ProtocolError& e) {
      res = json_error(http::status::bad_request, e.what(), version);
    } catch (const ApiError& e) {
      res = json_error(http::status(e.status), e.what(), version);
    } catch (const std::exception& e) {
      spdlog::error("{} {}: internal error: {}", std::string(req.method_string()), std::string(req.target()), e.what());
      res = json_error(http::status::internal_server_error, std::string("internal error: ") + e.what(), version);
    } catch (...) {
      spdlog::error("{} {}: internal error (unknown exception)", std::string(req.method_string()), std::string(req.target()));
      res = json_error(http::status::internal_server_error, "internal error", version);
    }
    if (req.method() == http::verb::head && !res.body().empty()) {
      const size_t n = res.body().size();
      res.body().clear();
      res.content_length(n);
    }
    metrics_.observe_request(label, std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count());
  } catch (...) {
    res = HttpResponse{http::status::internal_server_error, version};
    res.content_length(0);
  }
  return res;
}

HttpResponse Api::dispatch(const Route& r, HttpRequest& req) {
  const http::verb m = req.method();
  switch (r.id) {
    case RouteId::healthz: return json_response(http::status::ok, {{"status", "ok"}}, req.version());
    case RouteId::metrics: {
      HttpResponse res = bytes_response(metrics_.prometheus(sched_.counters(), clock_()), "text/plain; version=0.0.4", req.version());
      return res;
    }
    case RouteId::blob:
      if (m == http::verb::put) return put_blob(r.param, req);
      if (m == http::verb::head) return head_blob(r.param, req);
      return get_blob(r.param, req);
    case RouteId::jobs: return m == http::verb::post ? post_job(req) : list_jobs(req);
    case RouteId::job: return m == http::verb::delete_ ? delete_job(r.param, req) : get_job(r.param, req);
    case RouteId::job_result: return get_result(r.param, req);
    case RouteId::job_preview: return get_preview(r.param, req);
    case RouteId::job_spec: return get_spec(r.param, req);
    case RouteId::workers: return post_worker(req);
    case RouteId::worker_lease: return post_lease(r.param, req);
    case RouteId::lease_heartbeat: return post_heartbeat(r.param, req);
    case RouteId::lease_result: return put_result(r.param, req);
    case RouteId::lease_fail: return post_fail(r.param, req);
    case RouteId::lease_release: return post_release(r.param, req);
    case RouteId::none: break;
  }
  throw refusal(http::status::not_found, "no such endpoint");
}

// ---- blobs

HttpResponse Api::put_blob(const std::string& sha, HttpRequest& req) {
  if (!is_sha256_hex(sha))
    throw refusal(http::status::bad_request, "blob path must be 64 lowercase hex digits (a SHA-256), got '" + sha + "'");
  const PutBlobResult r = blobs_.put(sha, req.body());
  if (r.status == PutBlobResult::mismatch)
    throw refusal(http::status::bad_request, "body hashes to " + r.actual + ", not " + sha);
  if (r.status == PutBlobResult::created) spdlog::info("blob {}: stored ({} bytes)", sha, r.size);
  return json_response(r.status == PutBlobResult::created ? http::status::created : http::status::ok,
                       {{"sha256", sha}, {"size", r.size}}, req.version());
}

HttpResponse Api::head_blob(const std::string& sha, HttpRequest& req) {
  const std::optional<fs::path> f = blobs_.file(sha);
  HttpResponse res{f ? http::status::ok : http::status::not_found, req.version()};
  std::error_code ec;
  res.content_length(f ? uint64_t(fs::file_size(*f, ec)) : 0);
  if (f) res.set(http::field::content_type, "application/octet-stream");
  return res;
}

HttpResponse Api::get_blob(const std::string& sha, HttpRequest& req) {
  std::optional<std::string> bytes = blobs_.read(sha);
  if (!bytes) throw refusal(http::status::not_found, "blob " + sha + " is not stored");
  return bytes_response(std::move(*bytes), "application/octet-stream", req.version());
}

// ---- jobs

HttpResponse Api::post_job(HttpRequest& req) {
  // Admission: queued plus running jobs are bounded (checked again, atomically with add_job, below).
  auto unfinished_jobs = [this] {
    const SchedulerCounters c = sched_.counters();
    int64_t n = 0;
    for (const JobState st : {JobState::queued, JobState::running})
      if (const auto it = c.jobs.find(st); it != c.jobs.end()) n += it->second;
    return n;
  };
  auto queue_full = [&] {
    HttpResponse res = json_error(http::status::too_many_requests,
                                  "too many unfinished jobs: " + std::to_string(opt_.max_queued_jobs) +
                                      " are queued or running (--max-queued-jobs); retry later",
                                  req.version());
    res.set(http::field::retry_after, std::to_string(opt_.retry_after_seconds));
    return res;
  };
  if (unfinished_jobs() >= opt_.max_queued_jobs) return queue_full();

  const protocol::JobSubmission sub = protocol::parse_job_submission(req.body());
  const json& scene = sub.scene;
  const std::map<std::string, std::string>& assets = sub.assets;
  const protocol::SamplingSettings& sampling = sub.sampling;

  // Asset paths are names for blobs (the coordinator and workers never open them as files), but a scene that renders
  // here must render with `tessera render` too: the same paths the loader refuses are refused here.
  auto check_path = [](const std::string& rel, const std::string& where) {
    const fs::path p(rel);
    if (rel.empty()) throw refusal(http::status::bad_request, where + ": empty asset path");
    if (rel.find('\0') != std::string::npos) throw refusal(http::status::bad_request, where + ": asset path contains a NUL byte");
    if (p.is_absolute() || p.has_root_name() || p.has_root_directory())
      throw refusal(http::status::bad_request, where + ": absolute asset path '" + rel + "' (paths are relative to the scene's folder)");
    const fs::path n = p.lexically_normal();
    if (n.empty() || *n.begin() == "..")
      throw refusal(http::status::bad_request, where + ": asset path '" + rel + "' leaves the scene's folder");
  };
  for (const auto& [path, sha] : assets) check_path(path, "assets[\"" + path + "\"]");
  for (const std::string& path : scene_asset_paths(scene)) check_path(path, "scene");

  // Every asset the scene uses must be named and uploaded; say which are not, all at once.
  std::string missing;
  for (const std::string& path : scene_asset_paths(scene)) {
    const auto it = assets.find(path);
    std::string why;
    if (it == assets.end()) why = "not in \"assets\"";
    else if (!blobs_.has(it->second)) why = "not uploaded";
    else continue;
    missing += (missing.empty() ? "" : ", ") + path + " (" + why + ")";
  }
  if (!missing.empty()) throw refusal(http::status::bad_request, "missing assets: " + missing);

  const LoadOptions lo = sampling.load_options();
  LoadedScene loaded;
  try {
    loaded = load_scene_json(scene, "scene", [&](const std::string& rel, const std::string& jp) -> fs::path {
      const auto it = assets.find(rel);
      if (it == assets.end()) throw SceneError("scene: " + jp + ": asset '" + rel + "' is not in \"assets\"");
      std::optional<fs::path> f = blobs_.file(it->second);
      if (!f) throw SceneError("scene: " + jp + ": asset '" + rel + "' (" + it->second + ") is not uploaded");
      return *f;
    }, lo);
  } catch (const SceneError& e) {
    throw refusal(http::status::bad_request, e.what());
  }
  const Scene& s = loaded.scene;
  // Size limits: the merged image is held in memory, and width x height x spp bounds the work one job may ask for.
  const uint64_t pixels = uint64_t(s.width) * uint64_t(s.height);
  if (pixels > opt_.max_job_pixels)
    throw refusal(http::status::bad_request, "job too large: " + std::to_string(s.width) + "x" + std::to_string(s.height) +
                                                   " = " + std::to_string(pixels) + " pixels is over the limit of " +
                                                   std::to_string(opt_.max_job_pixels) + " (--max-job-pixels)");
  const bool adaptive = sampling.target_error > 0.0;
  const uint64_t per_pixel = adaptive ? uint64_t(sampling.max_spp) : uint64_t(s.settings.spp);
  const double samples = double(pixels) * double(per_pixel);
  if (samples > opt_.max_job_samples) {
    char text[256];
    std::snprintf(text, sizeof text, "job too large: %dx%d pixels x %llu %s = %.3g samples is over the limit of %.3g (--max-job-samples)",
                  s.width, s.height, static_cast<unsigned long long>(per_pixel), adaptive ? "max_spp" : "spp",
                  samples, opt_.max_job_samples);
    throw refusal(http::status::bad_request, text);
  }
  JobParams p;
  p.name = sub.name;
  p.priority = sub.priority;
  p.width = s.width;
  p.height = s.height;
  p.tile_size = sub.tile_size;
  p.spp = s.settings.spp;
  p.seed = sampling.seed;
  p.scene_hash = s.hash;

  protocol::JobSpec spec{scene, assets, sampling, p.width, p.height, p.tile_size};
  spec.sampling.spp = p.spp;
  std::unique_lock admit(admit_mu_);
  if (unfinished_jobs() >= opt_.max_queued_jobs) return queue_full();
  const std::string id = sched_.new_job_id();
  json record = spec;
  record["id"] = id;
  record["name"] = p.name;
  record["priority"] = p.priority;
  record["scene_hash"] = p.scene_hash;
  record["created_ms"] = clock_();
  jobs_.save_record(id, record);
  {
    std::lock_guard lock(mu_);
    specs_[id] = spec;
  }
  sched_.add_job(p, id);
  admit.unlock();
  spdlog::info("job {}: submitted '{}' {}x{} spp {} seed {} tile {} priority {} ({} tiles)", id, p.name, p.width, p.height,
               p.spp, p.seed, p.tile_size, p.priority, TileGrid(p.width, p.height, p.tile_size).count());
  for (const auto& w : loaded.warnings) spdlog::warn("job {}: {}", id, w);
  HttpResponse res = json_response(http::status::created, protocol::SubmitAnswer{id, loaded.warnings}, req.version());
  res.set(http::field::location, protocol::routes::job(id));
  return res;
}

HttpResponse Api::list_jobs(HttpRequest& req) {
  return json_response(http::status::ok, protocol::JobList{sched_.jobs()}, req.version());
}

HttpResponse Api::get_job(const std::string& id, HttpRequest& req) {
  const auto s = sched_.job(id);
  if (!s) throw refusal(http::status::not_found, "no job " + id);
  return json_response(http::status::ok, json(*s), req.version());
}

HttpResponse Api::delete_job(const std::string& id, HttpRequest& req) {
  const CancelResult c = sched_.cancel(id);
  if (c.status == CancelResult::unknown) throw refusal(http::status::not_found, "no job " + id);
  const auto s = sched_.job(id);
  if (c.status == CancelResult::already_ended)
    throw refusal(http::status::conflict, "job " + id + " already ended (" + to_string(s->state) + ")");
  drop_image(id);
  spdlog::info("job {}: cancelled, {} lease(s) revoked", id, c.revoked_leases);
  return json_response(http::status::ok, json(*s), req.version());
}

HttpResponse Api::get_result(const std::string& id, HttpRequest& req) {
  const auto s = sched_.job(id);
  if (!s) throw refusal(http::status::not_found, "no job " + id);
  if (s->state != JobState::done)
    throw refusal(http::status::conflict, "job " + id + " is " + to_string(s->state) + ", not done");
  HttpResponse res = bytes_response(read_file_bytes(jobs_.result_path(id)), "image/x-exr", req.version());
  return res;
}

HttpResponse Api::get_preview(const std::string& id, HttpRequest& req) {
  const auto s = sched_.job(id);
  if (!s) throw refusal(http::status::not_found, "no job " + id);
  std::vector<uint8_t> png;
  if (!is_final(s->state)) {
    png = image_for(id, s->params.width, s->params.height)->preview_png();
  } else if (s->state == JobState::done) {
    png = encode_png_srgb(read_exr(jobs_.result_path(id)).pixels);
  } else {
    png = encode_png_srgb(Image::make(s->params.width, s->params.height));
  }
  return bytes_response(std::string(png.begin(), png.end()), "image/png", req.version());
}

HttpResponse Api::get_spec(const std::string& id, HttpRequest& req) {
  {
    std::lock_guard lock(mu_);
    const auto it = specs_.find(id);
    if (it != specs_.end()) return json_response(http::status::ok, it->second, req.version());
  }
  if (!sched_.job(id)) throw refusal(http::status::not_found, "no job " + id);
  std::optional<json> rec = jobs_.load_record(id);
  if (!rec) throw refusal(http::status::not_found, "no record for job " + id);
  const auto spec = rec->get<protocol::JobSpec>();  // the record is the spec plus the job's facts
  {
    std::lock_guard lock(mu_);
    specs_.emplace(id, spec);
  }
  return json_response(http::status::ok, spec, req.version());
}

// ---- workers and leases

HttpResponse Api::post_worker(HttpRequest& req) {
  const protocol::WorkerHello hello = protocol::parse_worker_hello(req.body());
  const std::string id = sched_.register_worker(hello.name);
  spdlog::info("worker {}: registered '{}' ({} threads, version {})", id, hello.name, hello.threads,
               hello.version.empty() ? "?" : hello.version);
  const protocol::Registration reg{id, double(sched_.config().lease_ms) / 1000.0, double(opt_.heartbeat_seconds)};
  HttpResponse res = json_response(http::status::created, reg, req.version());
  res.set(http::field::location, protocol::routes::workers() + "/" + id);
  return res;
}

HttpResponse Api::post_lease(const std::string& worker, HttpRequest& req) {
  const AcquireResult r = sched_.acquire(worker);
  if (r.status == AcquireResult::unknown_worker)
    throw refusal(http::status::not_found, "unknown worker " + worker + ": register again");
  if (r.status == AcquireResult::no_work) {
    HttpResponse res{http::status::no_content, req.version()};
    return res;
  }
  const Lease& l = r.lease;
  spdlog::debug("job {} tile {} worker {}: leased as {}", l.job, l.tile, l.worker, l.id);
  return json_response(http::status::ok, l, req.version());
}

HttpResponse Api::post_heartbeat(const std::string& lease, HttpRequest& req) {
  const uint64_t rays = protocol::parse_heartbeat_report(req.body()).rays;
  const HeartbeatResult h = sched_.heartbeat(lease, rays);
  if (h.status == HeartbeatResult::unknown) throw refusal(http::status::not_found, "unknown lease " + lease);
  if (h.status == HeartbeatResult::gone)
    throw refusal(http::status::gone, "lease " + lease + " was revoked or expired: stop rendering this tile");
  metrics_.add_rays(rays, clock_());
  return json_response(http::status::ok, {{"deadline_ms", h.deadline_ms}}, req.version());
}

std::shared_ptr<JobImage> Api::image_for(const std::string& job, int width, int height) {
  std::lock_guard lock(mu_);
  auto& slot = images_[job];
  if (!slot) {
    // First use since the coordinator started: the done tiles are in the store. Holding the lock while reading them
    // means an upload finishing meanwhile either is among them or pastes into this image afterwards.
    auto img = std::make_shared<JobImage>(width, height);
    const auto s = sched_.job(job);
    if (s) {
      const TileGrid grid(s->params.width, s->params.height, s->params.tile_size);
      for (const auto& [index, bytes] : jobs_.tile_pixels(job)) {
        const PixelWindow w = grid.window(index);
        img->paste(tile_from_bytes(bytes, w.width(), w.height()), w);
      }
    }
    slot = std::move(img);
  }
  return slot;
}

void Api::recover() {
  for (const std::string& job : sched_.unfinalized_jobs()) {
    spdlog::info("job {}: every tile was done before the restart; writing the result", job);
    finalize(job);
  }
}

void Api::drop_image(const std::string& job) {
  std::lock_guard lock(mu_);
  images_.erase(job);
}

HttpResponse Api::put_result(const std::string& lease, HttpRequest& req) {
  uint64_t rays = 0;
  if (const auto h = req[ "X-Tessera-Rays" ]; !h.empty()) {
    const auto [ptr, ec] = std::from_chars(h.data(), h.data() + h.size(), rays);
    if (ec != std::errc() || ptr != h.data() + h.size())
      throw refusal(http::status::bad_request, "X-Tessera-Rays must be a non-negative integer (got '" + std::string(h) + "')");
  }
  auto settled = [&](const ResultClaim& c) -> std::optional<HttpResponse> {
    switch (c.status) {
      case ResultClaim::unknown: throw refusal(http::status::not_found, "unknown lease " + lease);
      case ResultClaim::discarded:
        spdlog::info("job {} tile {} worker {}: result discarded (job ended)", c.job, c.tile, c.worker);
        return json_response(http::status::gone, {{"status", "discarded"}}, req.version());
      case ResultClaim::duplicate:
        spdlog::info("job {} tile {} worker {}: duplicate result acknowledged", c.job, c.tile, c.worker);
        return json_response(http::status::ok, {{"status", "duplicate"}}, req.version());
      case ResultClaim::proceed: break;
    }
    return std::nullopt;
  };
  const ResultClaim pre = sched_.check_result(lease);
  if (auto r = settled(pre)) return std::move(*r);

  // Validate outside every lock: the EXR goes to a scratch file because the reader takes a path.
  const fs::path tmp = jobs_.scratch_dir() / ("result-" + lease + "-" + random_hex(6) + ".exr");
  {
    std::ofstream out(tmp, std::ios::binary);
    out.write(req.body().data(), std::streamsize(req.body().size()));
    if (!out.flush()) throw StorageError("cannot write " + tmp.string());
  }
  TileCheck check = check_tile_exr(tmp, pre.window, pre.width, pre.height);
  std::error_code rm_ec;
  fs::remove(tmp, rm_ec);
  if (check.error) {
    const FailResult f = sched_.fail(lease, "invalid result: " + *check.error);
    spdlog::warn("job {} tile {} worker {}: invalid result: {}{}", pre.job, pre.tile, pre.worker, *check.error,
                 f.job_failed ? " (job failed)" : f.blocklisted ? " (worker blocklisted for the job)" : "");
    if (f.job_failed) drop_image(pre.job);
    throw refusal(http::status::unprocessable_entity, "invalid result: " + *check.error);
  }

  const ResultClaim c = sched_.claim_result(lease);
  if (auto r = settled(c)) return std::move(*r);
  bool last = false;
  try {
    // Pasted before the tile counts as done: the upload that finishes the job writes the image, and every other
    // tile's pixels must be in it by then (pasting identical pixels twice is harmless if the store then fails).
    image_for(c.job, c.width, c.height)->paste(check.pixels, c.window);  // after a restart, rebuilt from the store first
    // Durable before acknowledged: the pixels and the tile's done state go to the store in one transaction.
    last = sched_.finish_result(lease, rays, tile_bytes(check.pixels)).last;
  } catch (...) {
    sched_.abandon_result(lease);
    throw;
  }
  metrics_.add_rays(rays, clock_());
  spdlog::info("job {} tile {} worker {}: merged", c.job, c.tile, c.worker);
  if (last) finalize(c.job);
  return json_response(http::status::ok, {{"status", "accepted"}}, req.version());
}

void Api::finalize(const std::string& job) {
  const auto s = sched_.job(job);
  if (!s) return;
  const auto img = image_for(job, s->params.width, s->params.height);
  const auto t0 = std::chrono::steady_clock::now();
  const int64_t now = clock_();
  const std::map<std::string, std::string> meta = {
      {"tessera:version", TESSERA_VERSION},
      {"tessera:job", job},
      {"tessera:name", s->params.name},
      {"tessera:sceneHash", s->params.scene_hash},
      {"tessera:spp", std::to_string(s->params.spp)},
      {"tessera:seed", std::to_string(s->params.seed)},
      {"tessera:tileSize", std::to_string(s->params.tile_size)},
      {"tessera:workers", join_workers(s->workers)},
      {"tessera:createdMs", std::to_string(s->created_ms)},
      {"tessera:startedMs", std::to_string(s->started_ms.value_or(0))},
      {"tessera:finishedMs", std::to_string(now)},
      {"tessera:renderSeconds", std::to_string(double(now - s->started_ms.value_or(now)) / 1000.0)}};
  try {
    img->write_exr(jobs_.result_path(job), meta);
  } catch (const std::exception& e) {
    spdlog::error("job {}: writing the result failed: {}", job, e.what());
    sched_.fail_job(job, std::string("writing the result failed: ") + e.what());
    drop_image(job);
    return;
  }
  sched_.complete_job(job);
  drop_image(job);
  spdlog::info("job {}: done, result written in {:.3f}s", job,
               std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count());
}

HttpResponse Api::post_fail(const std::string& lease, HttpRequest& req) {
  const std::string error = protocol::parse_fail_report(req.body()).error;
  const ResultClaim info = sched_.check_result(lease);
  const FailResult f = sched_.fail(lease, error);
  if (f.status == FailResult::unknown) throw refusal(http::status::not_found, "unknown lease " + lease);
  spdlog::warn("job {} tile {} worker {}: failed: {}{}", info.job, info.tile, info.worker, error,
               f.job_failed ? " (job failed)" : f.blocklisted ? " (worker blocklisted for the job)" : "");
  if (f.job_failed) drop_image(info.job);
  return json_response(http::status::ok, {{"status", "recorded"}}, req.version());
}

HttpResponse Api::post_release(const std::string& lease, HttpRequest& req) {
  protocol::parse_release(req.body());
  if (!sched_.release(lease)) throw refusal(http::status::not_found, "unknown lease " + lease);
  spdlog::debug("lease {}: released", lease);
  return json_response(http::status::ok, {{"status", "released"}}, req.version());
}

}  // namespace tessera::server
