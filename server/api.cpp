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

// A request the client got wrong; becomes an error response with this status.
struct HttpError : std::runtime_error {
  HttpError(http::status s, const std::string& what) : std::runtime_error(what), status(s) {}
  http::status status;
};

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

std::vector<std::string> split_path(std::string_view path) {
  std::vector<std::string> out;
  if (path.empty() || path[0] != '/') return {"\x01"};  // never matches
  size_t i = 1;
  while (true) {
    const size_t j = path.find('/', i);
    out.emplace_back(path.substr(i, j == std::string_view::npos ? std::string_view::npos : j - i));
    if (j == std::string_view::npos) break;
    i = j + 1;
  }
  return out;
}

// Parses a JSON object body and refuses keys outside `known`; an empty body is {} when allowed.
json parse_object(const HttpRequest& req, std::initializer_list<const char*> known, bool allow_empty) {
  const std::string& body = req.body();
  if (body.find_first_not_of(" \t\r\n") == std::string::npos) {
    if (allow_empty) return json::object();
    throw HttpError(http::status::bad_request, "request body is empty; expected a JSON object");
  }
  // Deep nesting is refused before parsing: printing, copying or destroying such a value recurses per level.
  if (json_nesting_depth(body) > kMaxSceneJsonDepth)
    throw HttpError(http::status::bad_request,
                    "malformed JSON: arrays/objects nested deeper than " + std::to_string(kMaxSceneJsonDepth) + " levels");
  json j;
  try {
    j = json::parse(body);
  } catch (const json::exception& e) {  // syntax errors, and numbers beyond the double range (out_of_range)
    throw HttpError(http::status::bad_request, std::string("malformed JSON: ") + e.what());
  }
  if (!j.is_object()) throw HttpError(http::status::bad_request, std::string("expected a JSON object, got ") + j.type_name());
  for (auto it = j.begin(); it != j.end(); ++it) {
    if (std::none_of(known.begin(), known.end(), [&](const char* k) { return it.key() == k; })) {
      std::string list;
      for (const char* k : known) list += (list.empty() ? "" : ", ") + std::string(k);
      throw HttpError(http::status::bad_request, "unknown key '" + it.key() + "' (known keys: " + list + ")");
    }
  }
  return j;
}

int64_t get_int(const json& j, const char* key, int64_t def, int64_t lo, int64_t hi) {
  if (!j.contains(key)) return def;
  const json& v = j[key];
  if (!v.is_number_integer() || (v.is_number_unsigned() && v.get<uint64_t>() > uint64_t(std::numeric_limits<int64_t>::max())) ||
      v.get<int64_t>() < lo || v.get<int64_t>() > hi)
    throw HttpError(http::status::bad_request, std::string("'") + key + "' must be an integer in " + std::to_string(lo) +
                                                   ".." + std::to_string(hi) + " (got " + v.dump() + ")");
  return v.get<int64_t>();
}

uint64_t get_uint(const json& j, const char* key, uint64_t def) {
  if (!j.contains(key)) return def;
  const json& v = j[key];
  if (!v.is_number_unsigned() && !(v.is_number_integer() && v.get<int64_t>() >= 0))
    throw HttpError(http::status::bad_request, std::string("'") + key + "' must be a non-negative integer (got " + v.dump() + ")");
  return v.get<uint64_t>();
}

std::string get_string(const json& j, const char* key, const std::string& def) {
  if (!j.contains(key)) return def;
  if (!j[key].is_string()) throw HttpError(http::status::bad_request, std::string("'") + key + "' must be a string (got " + j[key].dump() + ")");
  return j[key].get<std::string>();
}

json window_json(const PixelWindow& w) { return json::array({w.x0, w.y0, w.x1, w.y1}); }

json optional_ms(const std::optional<int64_t>& v) { return v ? json(*v) : json(nullptr); }

std::string join_workers(const std::vector<std::string>& v) {
  std::string s;
  for (const auto& w : v) s += (s.empty() ? "" : ",") + w;
  return s;
}

}  // namespace

Route match_route(std::string_view target) {
  const size_t q = target.find('?');
  const std::vector<std::string> p = split_path(target.substr(0, q));
  using V = http::verb;
  Route r;
  auto set = [&](RouteId id, std::string name, std::vector<V> methods, std::string param = "") {
    r.id = id;
    r.name = std::move(name);
    r.methods = std::move(methods);
    r.param = std::move(param);
  };
  const size_t n = p.size();
  for (const auto& s : p)
    if (s.empty()) return r;  // "//" or a trailing slash
  if (n == 1 && p[0] == "healthz") set(RouteId::healthz, "/healthz", {V::get});
  else if (n == 1 && p[0] == "metrics") set(RouteId::metrics, "/metrics", {V::get});
  else if (n < 2 || p[0] != "v1") return r;
  else if (n == 3 && p[1] == "blobs") set(RouteId::blob, "/v1/blobs/{sha256}", {V::put, V::head, V::get}, p[2]);
  else if (n == 2 && p[1] == "jobs") set(RouteId::jobs, "/v1/jobs", {V::get, V::post});
  else if (n == 3 && p[1] == "jobs") set(RouteId::job, "/v1/jobs/{id}", {V::get, V::delete_}, p[2]);
  else if (n == 4 && p[1] == "jobs" && p[3] == "result.exr") set(RouteId::job_result, "/v1/jobs/{id}/result.exr", {V::get}, p[2]);
  else if (n == 4 && p[1] == "jobs" && p[3] == "preview.png") set(RouteId::job_preview, "/v1/jobs/{id}/preview.png", {V::get}, p[2]);
  else if (n == 4 && p[1] == "jobs" && p[3] == "spec") set(RouteId::job_spec, "/v1/jobs/{id}/spec", {V::get}, p[2]);
  else if (n == 2 && p[1] == "workers") set(RouteId::workers, "/v1/workers", {V::post});
  else if (n == 4 && p[1] == "workers" && p[3] == "lease") set(RouteId::worker_lease, "/v1/workers/{wid}/lease", {V::post}, p[2]);
  else if (n == 4 && p[1] == "leases" && p[3] == "heartbeat") set(RouteId::lease_heartbeat, "/v1/leases/{lease}/heartbeat", {V::post}, p[2]);
  else if (n == 4 && p[1] == "leases" && p[3] == "result") set(RouteId::lease_result, "/v1/leases/{lease}/result", {V::put}, p[2]);
  else if (n == 4 && p[1] == "leases" && p[3] == "fail") set(RouteId::lease_fail, "/v1/leases/{lease}/fail", {V::post}, p[2]);
  else if (n == 4 && p[1] == "leases" && p[3] == "release") set(RouteId::lease_release, "/v1/leases/{lease}/release", {V::post}, p[2]);
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
    } catch (const HttpError& e) {
      res = json_error(e.status, e.what(), version);
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
  throw HttpError(http::status::not_found, "no such endpoint");
}

// ---- blobs

HttpResponse Api::put_blob(const std::string& sha, HttpRequest& req) {
  if (!is_sha256_hex(sha))
    throw HttpError(http::status::bad_request, "blob path must be 64 lowercase hex digits (a SHA-256), got '" + sha + "'");
  const PutBlobResult r = blobs_.put(sha, req.body());
  if (r.status == PutBlobResult::mismatch)
    throw HttpError(http::status::bad_request, "body hashes to " + r.actual + ", not " + sha);
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
  if (!bytes) throw HttpError(http::status::not_found, "blob " + sha + " is not stored");
  return bytes_response(std::move(*bytes), "application/octet-stream", req.version());
}

// ---- jobs

json Api::job_json(const JobStatus& s) const {
  const int64_t now = clock_();
  double render_seconds = 0;
  if (s.started_ms) render_seconds = double((s.finished_ms ? *s.finished_ms : now) - *s.started_ms) / 1000.0;
  return {{"id", s.id},
          {"name", s.params.name},
          {"state", to_string(s.state)},
          {"priority", s.params.priority},
          {"width", s.params.width},
          {"height", s.params.height},
          {"spp", s.params.spp},
          {"seed", s.params.seed},
          {"tile_size", s.params.tile_size},
          {"scene_hash", s.params.scene_hash},
          {"tiles", {{"total", s.tiles.total}, {"done", s.tiles.done}, {"leased", s.tiles.leased}, {"pending", s.tiles.pending}}},
          {"created_ms", s.created_ms},
          {"started_ms", optional_ms(s.started_ms)},
          {"finished_ms", optional_ms(s.finished_ms)},
          {"render_seconds", render_seconds},
          {"rays", s.rays},
          {"workers", s.workers},
          {"error", s.error ? json(*s.error) : json(nullptr)}};
}

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

  const json j = parse_object(req, {"scene", "assets", "spp", "seed", "tile_size", "priority", "name", "integrator",
                                    "target_error", "min_spp", "max_spp"}, false);
  if (!j.contains("scene")) throw HttpError(http::status::bad_request, "'scene' is missing");
  const json& scene = j["scene"];
  if (!scene.is_object()) throw HttpError(http::status::bad_request, std::string("'scene' must be a JSON object, got ") + scene.type_name());
  std::map<std::string, std::string> assets;
  if (j.contains("assets")) {
    if (!j["assets"].is_object()) throw HttpError(http::status::bad_request, "'assets' must be an object mapping scene paths to SHA-256 hashes");
    for (auto it = j["assets"].begin(); it != j["assets"].end(); ++it) {
      if (!it.value().is_string() || !is_sha256_hex(it.value().get<std::string>()))
        throw HttpError(http::status::bad_request, "assets[\"" + it.key() + "\"] must be a lowercase hex SHA-256 (got " + it.value().dump() + ")");
      assets.emplace(it.key(), it.value().get<std::string>());
    }
  }
  const int64_t spp_req = get_int(j, "spp", 0, 1, int64_t(1) << 20);
  const uint64_t seed = get_uint(j, "seed", 0);
  const int tile_size = int(get_int(j, "tile_size", 64, 1, 4096));
  const int priority = int(get_int(j, "priority", 0, std::numeric_limits<int>::min() + 1, std::numeric_limits<int>::max()));
  const std::string name = get_string(j, "name", "");
  const std::string integrator = get_string(j, "integrator", "");
  // Adaptive sampling (like `tessera render --target-error`): each pixel's sample count depends only on its own
  // samples, so any tile split still gives the same bits.
  double target_error = 0.0;
  if (j.contains("target_error")) {
    const json& v = j["target_error"];
    if (!v.is_number() || !(v.get<double>() > 0.0) || !(v.get<double>() <= 1e6))
      throw HttpError(http::status::bad_request, "'target_error' must be a number in (0, 1e6] (got " + v.dump() + ")");
    target_error = v.get<double>();
  }
  const int64_t min_spp = get_int(j, "min_spp", 16, 1, int64_t(1) << 20);
  const int64_t max_spp = get_int(j, "max_spp", 1024, 1, int64_t(1) << 20);
  if (target_error == 0.0 && (j.contains("min_spp") || j.contains("max_spp")))
    throw HttpError(http::status::bad_request, "'min_spp' and 'max_spp' apply only with 'target_error'");
  if (min_spp > max_spp)
    throw HttpError(http::status::bad_request, "'min_spp' (" + std::to_string(min_spp) + ") is larger than 'max_spp' (" +
                                                   std::to_string(max_spp) + ")");
  if (!integrator.empty() && integrator != "direct" && integrator != "intersection_test")
    throw HttpError(http::status::bad_request, "'integrator' must be \"direct\" or \"intersection_test\" (got \"" + integrator + "\")");

  // Asset paths are names for blobs (the coordinator and workers never open them as files), but a scene that renders
  // here must render with `tessera render` too: the same paths the loader refuses are refused here.
  auto check_path = [](const std::string& rel, const std::string& where) {
    const fs::path p(rel);
    if (rel.empty()) throw HttpError(http::status::bad_request, where + ": empty asset path");
    if (rel.find('\0') != std::string::npos) throw HttpError(http::status::bad_request, where + ": asset path contains a NUL byte");
    if (p.is_absolute() || p.has_root_name() || p.has_root_directory())
      throw HttpError(http::status::bad_request, where + ": absolute asset path '" + rel + "' (paths are relative to the scene's folder)");
    const fs::path n = p.lexically_normal();
    if (n.empty() || *n.begin() == "..")
      throw HttpError(http::status::bad_request, where + ": asset path '" + rel + "' leaves the scene's folder");
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
  if (!missing.empty()) throw HttpError(http::status::bad_request, "missing assets: " + missing);

  LoadOptions lo;
  lo.force_direct = !integrator.empty();
  if (spp_req) lo.spp = uint32_t(spp_req);
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
    throw HttpError(http::status::bad_request, e.what());
  }
  const Scene& s = loaded.scene;
  // Size limits: the merged image is held in memory, and width x height x spp bounds the work one job may ask for.
  const uint64_t pixels = uint64_t(s.width) * uint64_t(s.height);
  if (pixels > opt_.max_job_pixels)
    throw HttpError(http::status::bad_request, "job too large: " + std::to_string(s.width) + "x" + std::to_string(s.height) +
                                                   " = " + std::to_string(pixels) + " pixels is over the limit of " +
                                                   std::to_string(opt_.max_job_pixels) + " (--max-job-pixels)");
  const uint64_t per_pixel = target_error > 0.0 ? uint64_t(max_spp) : uint64_t(s.settings.spp);
  const double samples = double(pixels) * double(per_pixel);
  if (samples > opt_.max_job_samples) {
    char text[256];
    std::snprintf(text, sizeof text, "job too large: %dx%d pixels x %llu %s = %.3g samples is over the limit of %.3g (--max-job-samples)",
                  s.width, s.height, static_cast<unsigned long long>(per_pixel), target_error > 0.0 ? "max_spp" : "spp",
                  samples, opt_.max_job_samples);
    throw HttpError(http::status::bad_request, text);
  }
  JobParams p;
  p.name = name;
  p.priority = priority;
  p.width = s.width;
  p.height = s.height;
  p.tile_size = tile_size;
  p.spp = s.settings.spp;
  p.seed = seed;
  p.scene_hash = s.hash;

  json spec = {{"scene", scene}, {"assets", assets}, {"spp", p.spp}, {"seed", p.seed}, {"width", p.width},
               {"height", p.height}, {"tile_size", p.tile_size}};
  if (!integrator.empty()) spec["integrator"] = integrator;
  if (target_error > 0.0) {
    spec["target_error"] = target_error;
    spec["min_spp"] = min_spp;
    spec["max_spp"] = max_spp;
  }
  std::unique_lock admit(admit_mu_);
  if (unfinished_jobs() >= opt_.max_queued_jobs) return queue_full();
  const std::string id = sched_.new_job_id();
  json record = spec;
  record["id"] = id;
  record["name"] = name;
  record["priority"] = priority;
  record["scene_hash"] = p.scene_hash;
  record["created_ms"] = clock_();
  jobs_.save_record(id, record);
  {
    std::lock_guard lock(mu_);
    specs_[id] = spec;
  }
  sched_.add_job(p, id);
  admit.unlock();
  spdlog::info("job {}: submitted '{}' {}x{} spp {} seed {} tile {} priority {} ({} tiles)", id, name, p.width, p.height,
               p.spp, p.seed, p.tile_size, p.priority, TileGrid(p.width, p.height, p.tile_size).count());
  for (const auto& w : loaded.warnings) spdlog::warn("job {}: {}", id, w);
  HttpResponse res = json_response(http::status::created, {{"id", id}, {"warnings", loaded.warnings}}, req.version());
  res.set(http::field::location, "/v1/jobs/" + id);
  return res;
}

HttpResponse Api::list_jobs(HttpRequest& req) {
  json list = json::array();
  for (const JobStatus& s : sched_.jobs()) list.push_back(job_json(s));
  return json_response(http::status::ok, {{"jobs", list}}, req.version());
}

HttpResponse Api::get_job(const std::string& id, HttpRequest& req) {
  const auto s = sched_.job(id);
  if (!s) throw HttpError(http::status::not_found, "no job " + id);
  return json_response(http::status::ok, job_json(*s), req.version());
}

HttpResponse Api::delete_job(const std::string& id, HttpRequest& req) {
  const CancelResult c = sched_.cancel(id);
  if (c.status == CancelResult::unknown) throw HttpError(http::status::not_found, "no job " + id);
  const auto s = sched_.job(id);
  if (c.status == CancelResult::already_ended)
    throw HttpError(http::status::conflict, "job " + id + " already ended (" + to_string(s->state) + ")");
  drop_image(id);
  spdlog::info("job {}: cancelled, {} lease(s) revoked", id, c.revoked_leases);
  return json_response(http::status::ok, job_json(*s), req.version());
}

HttpResponse Api::get_result(const std::string& id, HttpRequest& req) {
  const auto s = sched_.job(id);
  if (!s) throw HttpError(http::status::not_found, "no job " + id);
  if (s->state != JobState::done)
    throw HttpError(http::status::conflict, "job " + id + " is " + to_string(s->state) + ", not done");
  HttpResponse res = bytes_response(read_file_bytes(jobs_.result_path(id)), "image/x-exr", req.version());
  return res;
}

HttpResponse Api::get_preview(const std::string& id, HttpRequest& req) {
  const auto s = sched_.job(id);
  if (!s) throw HttpError(http::status::not_found, "no job " + id);
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
  if (!sched_.job(id)) throw HttpError(http::status::not_found, "no job " + id);
  std::optional<json> rec = jobs_.load_record(id);
  if (!rec) throw HttpError(http::status::not_found, "no record for job " + id);
  json spec;
  for (const char* k : {"scene", "assets", "spp", "seed", "width", "height", "tile_size", "integrator", "target_error",
                        "min_spp", "max_spp"})
    if (rec->contains(k)) spec[k] = (*rec)[k];
  return json_response(http::status::ok, spec, req.version());
}

// ---- workers and leases

HttpResponse Api::post_worker(HttpRequest& req) {
  const json j = parse_object(req, {"name", "threads", "version"}, true);
  const std::string name = get_string(j, "name", "");
  const int64_t threads = get_int(j, "threads", 0, 0, 1 << 20);
  const std::string version = get_string(j, "version", "");
  const std::string id = sched_.register_worker(name);
  spdlog::info("worker {}: registered '{}' ({} threads, version {})", id, name, threads, version.empty() ? "?" : version);
  HttpResponse res = json_response(http::status::created,
                                   {{"id", id},
                                    {"lease_seconds", sched_.config().lease_ms % 1000 == 0
                                                          ? json(sched_.config().lease_ms / 1000)
                                                          : json(double(sched_.config().lease_ms) / 1000.0)},
                                    {"heartbeat_seconds", opt_.heartbeat_seconds}},
                                   req.version());
  res.set(http::field::location, "/v1/workers/" + id);
  return res;
}

HttpResponse Api::post_lease(const std::string& worker, HttpRequest& req) {
  const AcquireResult r = sched_.acquire(worker);
  if (r.status == AcquireResult::unknown_worker)
    throw HttpError(http::status::not_found, "unknown worker " + worker + ": register again");
  if (r.status == AcquireResult::no_work) {
    HttpResponse res{http::status::no_content, req.version()};
    return res;
  }
  const Lease& l = r.lease;
  spdlog::debug("job {} tile {} worker {}: leased as {}", l.job, l.tile, l.worker, l.id);
  return json_response(http::status::ok,
                       {{"lease", l.id}, {"job", l.job}, {"tile", l.tile}, {"window", window_json(l.window)}, {"spp", l.spp},
                        {"seed", l.seed}, {"scene_hash", l.scene_hash}, {"deadline_ms", l.deadline_ms}},
                       req.version());
}

HttpResponse Api::post_heartbeat(const std::string& lease, HttpRequest& req) {
  const json j = parse_object(req, {"rays"}, true);
  const uint64_t rays = get_uint(j, "rays", 0);
  const HeartbeatResult h = sched_.heartbeat(lease, rays);
  if (h.status == HeartbeatResult::unknown) throw HttpError(http::status::not_found, "unknown lease " + lease);
  if (h.status == HeartbeatResult::gone)
    throw HttpError(http::status::gone, "lease " + lease + " was revoked or expired: stop rendering this tile");
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
      throw HttpError(http::status::bad_request, "X-Tessera-Rays must be a non-negative integer (got '" + std::string(h) + "')");
  }
  auto settled = [&](const ResultClaim& c) -> std::optional<HttpResponse> {
    switch (c.status) {
      case ResultClaim::unknown: throw HttpError(http::status::not_found, "unknown lease " + lease);
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
    throw HttpError(http::status::unprocessable_entity, "invalid result: " + *check.error);
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
  json adaptive;  // the job's adaptive-sampling options, recorded like `tessera render` records them
  {
    std::lock_guard lock(mu_);
    const auto it = specs_.find(job);
    if (it != specs_.end() && it->second.contains("target_error")) adaptive = it->second;
  }
  std::map<std::string, std::string> meta = {
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
  if (!adaptive.is_null()) {
    meta["tessera:spp"] = "adaptive";
    meta["tessera:targetError"] = std::to_string(adaptive["target_error"].get<float>());
    meta["tessera:minSpp"] = std::to_string(adaptive["min_spp"].get<uint32_t>());
    meta["tessera:maxSpp"] = std::to_string(adaptive["max_spp"].get<uint32_t>());
  }
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
  const json j = parse_object(req, {"error"}, true);
  const std::string error = get_string(j, "error", "(no error text)");
  const ResultClaim info = sched_.check_result(lease);
  const FailResult f = sched_.fail(lease, error);
  if (f.status == FailResult::unknown) throw HttpError(http::status::not_found, "unknown lease " + lease);
  spdlog::warn("job {} tile {} worker {}: failed: {}{}", info.job, info.tile, info.worker, error,
               f.job_failed ? " (job failed)" : f.blocklisted ? " (worker blocklisted for the job)" : "");
  if (f.job_failed) drop_image(info.job);
  return json_response(http::status::ok, {{"status", "recorded"}}, req.version());
}

HttpResponse Api::post_release(const std::string& lease, HttpRequest& req) {
  parse_object(req, {}, true);
  if (!sched_.release(lease)) throw HttpError(http::status::not_found, "unknown lease " + lease);
  spdlog::debug("lease {}: released", lease);
  return json_response(http::status::ok, {{"status", "released"}}, req.version());
}

}  // namespace tessera::server
