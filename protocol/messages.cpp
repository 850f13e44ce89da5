#include "protocol/messages.h"

#include "protocol/tags.h"
#include "protocol/tile.h"

#include <algorithm>
#include <charconv>

#include "core/geometry/split_method.h"
#include "core/util/enum_names.h"
#include "core/render/light_sampling.h"
#include "core/util/sha256.h"

namespace tessera::protocol {

using nlohmann::json;

namespace {

// A strategy override: "" (the scene's) or one of the names in `table`.
template <std::size_t N>
std::string strategy(const json& j, const char* key, const std::string_view (&table)[N]) {
  const std::string v = request_string(j, key, "");
  if (j.contains(key) && !enum_from_name<int>(v, table)) {
    std::string list;
    for (std::string_view n : table) list += (list.empty() ? "" : ", ") + std::string(n);
    throw ProtocolError(std::string("'") + key + "' must be one of " + list + " (got \"" + v + "\")");
  }
  return v;
}

// The "layers" of a request: an array of distinct layer names.
LayerSet request_layers(const json& j) {
  LayerSet set;
  if (!j.contains("layers")) return set;
  const json& v = j["layers"];
  const auto bad = [&](const std::string& why) {
    std::string list;
    for (std::string_view n : kLayerNames) list += (list.empty() ? "" : ", ") + std::string(n);
    return ProtocolError("'layers' must be an array of layer names (" + list + ")" + why);
  };
  if (!v.is_array()) throw bad(" (got " + v.dump() + ")");
  for (const json& e : v) {
    const std::optional<Layer> l = e.is_string() ? enum_from_name<Layer>(e.get<std::string>(), kLayerNames) : std::nullopt;
    if (!l) throw bad(" (got " + e.dump() + ")");
    if (set.has(*l)) throw bad(": " + e.dump() + " is named twice");
    set.add(*l);
  }
  return set;
}

// The layers as a JSON array of names.
json layer_names(LayerSet layers) {
  json a = json::array();
  for (const Layer l : layers.list()) a.push_back(std::string(enum_name(l, kLayerNames)));
  return a;
}

// Sampling settings of a request object, checked with the coordinator's sentences.
SamplingSettings request_sampling(const json& j) {
  SamplingSettings s;
  s.spp = uint32_t(request_int(j, "spp", 0, 1, int64_t(1) << 20));
  s.seed = request_uint(j, "seed", 0);
  s.integrator = request_string(j, "integrator", "");
  // Adaptive sampling (like `tessera render --target-error`): each pixel's sample count depends only on its own
  // samples, so any tile split still gives the same bits.
  if (j.contains("target_error")) {
    const json& v = j["target_error"];
    if (!v.is_number() || !(v.get<double>() > 0.0) || !(v.get<double>() <= 1e6))
      throw ProtocolError("'target_error' must be a number in (0, 1e6] (got " + v.dump() + ")");
    s.target_error = v.get<double>();
  }
  s.min_spp = uint32_t(request_int(j, "min_spp", kDefaultMinSpp, 1, int64_t(1) << 20));
  s.max_spp = uint32_t(request_int(j, "max_spp", kDefaultMaxSpp, 1, int64_t(1) << 20));
  if (s.target_error == 0.0 && (j.contains("min_spp") || j.contains("max_spp") || j.contains("error_floor")))
    throw ProtocolError(j.contains("error_floor") ? "'error_floor' applies only with 'target_error'"
                                                  : "'min_spp' and 'max_spp' apply only with 'target_error'");
  if (s.min_spp > s.max_spp)
    throw ProtocolError("'min_spp' (" + std::to_string(s.min_spp) + ") is larger than 'max_spp' (" +
                        std::to_string(s.max_spp) + ")");
  if (!s.integrator.empty() && s.integrator != "direct" && s.integrator != "intersection_test")
    throw ProtocolError("'integrator' must be \"direct\" or \"intersection_test\" (got \"" + s.integrator + "\")");
  if (j.contains("error_floor")) {
    const json& v = j["error_floor"];
    if (!v.is_number() || !(v.get<double>() > 0.0) || !(v.get<double>() <= 1e6))
      throw ProtocolError("'error_floor' must be a number in (0, 1e6] (got " + v.dump() + ")");
    s.error_floor = v.get<double>();
  }
  s.replicates = uint32_t(request_int(j, "replicates", 1, 1, kMaxReplicates));
  s.area_sampling = strategy(j, "area_sampling", kAreaSamplingNames);
  s.env_sampling = strategy(j, "env_sampling", kEnvSamplingNames);
  s.bvh = strategy(j, "bvh", kSplitMethodNames);
  s.layers = request_layers(j);
  return s;
}

// Writes the settings into j; those at their defaults are left out, so older readers see the keys they know.
void put_sampling(json& j, const SamplingSettings& s) {
  if (s.spp) j["spp"] = s.spp;
  j["seed"] = s.seed;
  if (!s.integrator.empty()) j["integrator"] = s.integrator;
  if (s.target_error > 0.0) {
    j["target_error"] = s.target_error;
    j["min_spp"] = s.min_spp;
    j["max_spp"] = s.max_spp;
    if (s.error_floor != SamplingSettings{}.error_floor) j["error_floor"] = s.error_floor;
  }
  if (s.replicates != 1) j["replicates"] = s.replicates;
  if (!s.area_sampling.empty()) j["area_sampling"] = s.area_sampling;
  if (!s.env_sampling.empty()) j["env_sampling"] = s.env_sampling;
  if (!s.bvh.empty()) j["bvh"] = s.bvh;
  if (!s.layers.empty()) j["layers"] = layer_names(s.layers);
}

// Reads settings written by put_sampling (a spec from the coordinator).
SamplingSettings answer_sampling(const json& j, const char* msg) {
  SamplingSettings s;
  s.spp = answer_field<uint32_t>(j, "spp", msg);
  s.seed = answer_field_or<uint64_t>(j, "seed", msg, 0);
  s.integrator = answer_field_or<std::string>(j, "integrator", msg, "");
  s.target_error = answer_field_or<double>(j, "target_error", msg, 0.0);
  s.min_spp = answer_field_or<uint32_t>(j, "min_spp", msg, kDefaultMinSpp);
  s.max_spp = answer_field_or<uint32_t>(j, "max_spp", msg, kDefaultMaxSpp);
  s.error_floor = answer_field_or<double>(j, "error_floor", msg, SamplingSettings{}.error_floor);
  s.replicates = answer_field_or<uint32_t>(j, "replicates", msg, 1);
  s.area_sampling = answer_field_or<std::string>(j, "area_sampling", msg, "");
  s.env_sampling = answer_field_or<std::string>(j, "env_sampling", msg, "");
  s.bvh = answer_field_or<std::string>(j, "bvh", msg, "");
  if (j.contains("layers")) {
    try {
      s.layers = request_layers(j);
    } catch (const ProtocolError& e) {
      throw ProtocolError(std::string(msg) + ": " + e.what());
    }
  }
  if (!(s.target_error >= 0.0) || s.min_spp < 1 || s.min_spp > s.max_spp || !(s.error_floor > 0.0))
    throw ProtocolError(std::string(msg) + ": bad adaptive sampling settings (target_error, min_spp, max_spp, error_floor)");
  if (s.replicates < 1 || s.replicates > kMaxReplicates)
    throw ProtocolError(std::string(msg) + ": bad replicates " + std::to_string(s.replicates));
  return s;
}

// The "assets" of a submission or of one of its frames (`where` prefixes the sentence: "" or "frames[3].").
std::map<std::string, std::string> request_assets(const json& j, const std::string& where = "") {
  std::map<std::string, std::string> assets;
  if (!j.contains("assets")) return assets;
  if (!j["assets"].is_object())
    throw ProtocolError("'" + where + "assets' must be an object mapping scene paths to SHA-256 hashes");
  for (auto it = j["assets"].begin(); it != j["assets"].end(); ++it) {
    if (!it.value().is_string() || !is_sha256_hex(it.value().get<std::string>()))
      throw ProtocolError(where + "assets[\"" + it.key() + "\"] must be a lowercase hex SHA-256 (got " +
                          it.value().dump() + ")");
    assets.emplace(it.key(), it.value().get<std::string>());
  }
  return assets;
}

// The "frames" of a sequence's submission: objects {number, scene, assets?} with unique numbers, sorted by number.
std::vector<FrameSubmission> request_frames(json& f) {
  if (!f.is_array() || f.empty())
    throw ProtocolError("'frames' must be a non-empty array of {\"number\", \"scene\"} objects");
  std::vector<FrameSubmission> frames;
  frames.reserve(f.size());
  for (size_t i = 0; i < f.size(); ++i) {
    const std::string where = "frames[" + std::to_string(i) + "]";
    json& o = f[i];
    if (!o.is_object()) throw ProtocolError("'" + where + "' must be an object {\"number\", \"scene\"}");
    for (auto it = o.begin(); it != o.end(); ++it)
      if (it.key() != "number" && it.key() != "scene" && it.key() != "assets")
        throw ProtocolError("'" + where + "' has an unknown key '" + it.key() + "' (known: number, scene, assets)");
    FrameSubmission fr;
    if (!o.contains("number") || !o["number"].is_number_integer() || o["number"].get<int64_t>() < 0 ||
        o["number"].get<int64_t>() > kMaxFrameNumber)
      throw ProtocolError("'" + where + ".number' must be a frame number from 0 to " + std::to_string(kMaxFrameNumber));
    fr.number = o["number"].get<int64_t>();
    if (!o.contains("scene") || !o["scene"].is_object())
      throw ProtocolError("'" + where + ".scene' (frame " + std::to_string(fr.number) + ") must be a JSON object");
    fr.assets = request_assets(o, where + ".");
    fr.scene = std::move(o["scene"]);
    frames.push_back(std::move(fr));
  }
  std::sort(frames.begin(), frames.end(), [](const auto& a, const auto& b) { return a.number < b.number; });
  for (size_t i = 1; i < frames.size(); ++i)
    if (frames[i].number == frames[i - 1].number)
      throw ProtocolError("frame " + std::to_string(frames[i].number) + " appears twice in 'frames'");
  return frames;
}

}  // namespace

void to_json(json& j, const SamplingSettings& s) {
  j = json::object();
  put_sampling(j, s);
}

LoadOptions SamplingSettings::load_options() const {
  LoadOptions lo;
  lo.force_direct = !integrator.empty();
  if (spp) lo.spp = spp;
  lo.area_sampling = enum_from_name<AreaSampling>(area_sampling, kAreaSamplingNames);
  lo.env_sampling = enum_from_name<EnvSampling>(env_sampling, kEnvSamplingNames);
  lo.bvh = enum_from_name<SplitMethod>(bvh, kSplitMethodNames);
  return lo;
}

namespace {

// The shortest text that reads back as exactly v.
std::string exact_text(float v) {
  char buf[32];
  const auto r = std::to_chars(buf, buf + sizeof buf, v);
  return std::string(buf, r.ptr);
}

}  // namespace

std::map<std::string, std::string> SamplingSettings::metadata() const {
  std::map<std::string, std::string> m;
  m["tessera:seed"] = std::to_string(seed);
  m["tessera:spp"] = target_error > 0.0 ? std::string("adaptive") : std::to_string(spp);
  if (target_error > 0.0) {
    m["tessera:targetError"] = exact_text(float(target_error));
    m["tessera:minSpp"] = std::to_string(min_spp);
    m["tessera:maxSpp"] = std::to_string(max_spp);
    m["tessera:errorFloor"] = exact_text(float(error_floor));
  }
  m["tessera:replicates"] = std::to_string(replicates);
  if (!area_sampling.empty()) m["tessera:areaSamplingOverride"] = area_sampling;
  if (!env_sampling.empty()) m["tessera:envSamplingOverride"] = env_sampling;
  if (!bvh.empty()) m["tessera:bvhOverride"] = bvh;
  if (!layers.empty()) m["tessera:layers"] = layers_to_string(layers);
  return m;
}

void SamplingSettings::apply_to(RenderOptions& o) const {
  o.seed = seed;
  o.target_error = float(target_error);
  o.min_spp = min_spp;
  o.max_spp = max_spp;
  o.error_floor = float(error_floor);
  o.replicates = replicates;
  o.layers = layers;
}

void to_json(json& j, const JobSubmission& s) {
  j = {{"assets", s.assets}, {"tile_size", s.tile_size}, {"priority", s.priority}, {"name", s.name}};
  if (s.frames.empty()) {
    j["scene"] = s.scene;
  } else {
    json frames = json::array();
    for (const FrameSubmission& f : s.frames) {
      json o = {{"number", f.number}, {"scene", f.scene}};
      if (!f.assets.empty()) o["assets"] = f.assets;
      frames.push_back(std::move(o));
    }
    j["frames"] = std::move(frames);
    if (s.frame_order != FrameOrder::in_order) j["frame_order"] = to_string(s.frame_order);
  }
  if (s.tile_timeout_seconds != kDefaultTileTimeoutSeconds) j["tile_timeout_seconds"] = s.tile_timeout_seconds;
  if (!s.require.empty()) j["require"] = s.require;
  if (s.max_workers) j["max_workers"] = s.max_workers;
  put_sampling(j, s.sampling);
  if (s.resumable) j["resumable"] = true;
  put_pipeline(j, s.pipeline);
}

namespace {
// A job priority field: any int but INT_MIN (its negation orders the queue).
int request_priority(const json& j) {
  return int(request_int(j, "priority", kDefaultPriority, std::numeric_limits<int>::min() + 1,
                         std::numeric_limits<int>::max()));
}
}  // namespace

JobSubmission parse_job_submission(const std::string& body) {
  json j = parse_request_object(
      body, {"scene", "assets", "frames", "frame_order", "spp", "seed", "tile_size", "priority", "name", "integrator",
             "target_error", "min_spp", "max_spp", "error_floor", "replicates", "area_sampling", "env_sampling", "bvh", "layers",
             "resumable", "tile_timeout_seconds", "require", "max_workers", "after", "per_frame", "then", "fps", "notify",
             "notify_frames"},
      false);
  JobSubmission s;
  if (j.contains("frames")) {
    if (j.contains("scene")) throw ProtocolError("a submission has either 'scene' (one image) or 'frames' (a sequence)");
    s.frames = request_frames(j["frames"]);
    if (j.contains("frame_order")) {
      try {
        s.frame_order = frame_order_from_string(request_string(j, "frame_order", ""));
      } catch (const std::invalid_argument&) {
        throw ProtocolError("'frame_order' must be \"in_order\" or \"any\" (got " + j["frame_order"].dump() + ")");
      }
    }
  } else {
    if (!j.contains("scene")) throw ProtocolError("'scene' is missing (or 'frames', for a sequence)");
    if (j.contains("frame_order")) throw ProtocolError("'frame_order' applies only to a sequence ('frames')");
    s.scene = j["scene"];
    if (!s.scene.is_object())
      throw ProtocolError(std::string("'scene' must be a JSON object, got ") + s.scene.type_name());
  }
  s.assets = request_assets(j);
  s.tile_size = int(request_int(j, "tile_size", kDefaultTileSize, 1, 4096));
  s.priority = request_priority(j);
  s.name = request_bounded_string(j, "name", "", kMaxNameBytes);
  s.tile_timeout_seconds = request_int(j, "tile_timeout_seconds", kDefaultTileTimeoutSeconds, 1, kMaxTileTimeoutSeconds);
  if (auto tags = request_strings(j, "require", kMaxTags)) s.require = checked_tags(std::move(*tags), "require");
  s.max_workers = request_int(j, "max_workers", 0, 0, 1 << 30);
  s.sampling = request_sampling(j);
  if (j.contains("resumable")) {
    if (!j["resumable"].is_boolean()) throw ProtocolError("'resumable' must be true or false (got " + j["resumable"].dump() + ")");
    s.resumable = j["resumable"].get<bool>();
  }
  if (s.resumable && s.sampling.target_error > 0.0)
    throw ProtocolError("'resumable' needs a fixed spp: with 'target_error' each pixel stops at its own sample count, so "
                        "there is no common spp to raise later");
  s.pipeline = request_pipeline(j);
  if (s.pipeline.per_frame && s.frames.empty())
    throw ProtocolError("'per_frame' applies only to a sequence ('frames'): frame k waits for frame k of each job in "
                        "'after'");
  if (s.pipeline.notify_frames && s.frames.empty())
    throw ProtocolError("'notify_frames' applies only to a sequence ('frames'): it tells of each frame done");
  return s;
}

void to_json(json& j, const JobPatch& p) {
  j = json::object();
  if (p.priority) j["priority"] = *p.priority;
  if (p.spp) j["spp"] = *p.spp;
}

JobPatch parse_job_patch(const std::string& body) {
  const json j = parse_request_object(body, {"priority", "spp"}, false);
  if (!j.contains("priority") && !j.contains("spp"))
    throw ProtocolError("a job patch needs 'priority' or 'spp' (or both): they are what it can change");
  JobPatch p;
  if (j.contains("priority")) p.priority = request_priority(j);
  if (j.contains("spp")) p.spp = uint32_t(request_int(j, "spp", 0, 1, int64_t(1) << 20));
  return p;
}

void to_json(json& j, const SubmitAnswer& a) { j = {{"id", a.id}, {"warnings", a.warnings}}; }

void from_json(const json& j, SubmitAnswer& a) {
  a.id = answer_field<std::string>(j, "id", "job submission");
  a.warnings = answer_field_or<std::vector<std::string>>(j, "warnings", "job submission", {});
}

void to_json(json& j, const JobSpec& s) {
  j = {{"scene", s.scene}, {"assets", s.assets}, {"width", s.width}, {"height", s.height}, {"tile_size", s.tile_size}};
  put_sampling(j, s.sampling);
  j["spp"] = s.sampling.spp;
  if (s.resumable) j["resumable"] = true;
}

void from_json(const json& j, JobSpec& s) {
  constexpr const char* kMsg = "job spec";
  if (!j.is_object() || !j.contains("scene") || !j["scene"].is_object())
    throw ProtocolError("job spec: missing \"scene\" object");
  s.scene = j["scene"];
  s.assets = answer_field_or<std::map<std::string, std::string>>(j, "assets", kMsg, {});
  s.sampling = answer_sampling(j, kMsg);
  s.width = answer_field<int>(j, "width", kMsg);
  s.height = answer_field<int>(j, "height", kMsg);
  s.tile_size = answer_field_or<int>(j, "tile_size", kMsg, kDefaultTileSize);
  s.resumable = answer_field_or<bool>(j, "resumable", kMsg, false);
}

void to_json(json& j, const BlobQuery& q) { j = {{"sha256", q.sha256}}; }

BlobQuery parse_blob_query(const std::string& body) {
  const json j = parse_request_object(body, {"sha256"}, false);
  std::optional<std::vector<std::string>> hashes = request_strings(j, "sha256", kMaxBlobQuery);
  if (!hashes) throw ProtocolError("\"sha256\" must be an array of blob hashes (64 lowercase hex digits each)");
  for (size_t i = 0; i < hashes->size(); ++i)
    if (!is_sha256_hex((*hashes)[i]))
      throw ProtocolError("\"sha256\"[" + std::to_string(i) + "] is not 64 lowercase hex digits (a SHA-256)");
  return BlobQuery{std::move(*hashes)};
}

void to_json(json& j, const BlobQueryAnswer& a) { j = {{"missing", a.missing}}; }

void from_json(const json& j, BlobQueryAnswer& a) {
  a.missing = answer_field<std::vector<std::string>>(j, "missing", "blob query answer");
}

void to_json(json& j, const WorkerHello& h) {
  j = {{"name", h.name}, {"threads", h.threads}, {"version", h.version}};
  if (!h.tags.empty()) j["tags"] = h.tags;
}

WorkerHello parse_worker_hello(const std::string& body) {
  const json j = parse_request_object(body, {"name", "threads", "version", "tags"}, true);
  WorkerHello h;
  h.name = request_bounded_string(j, "name", "", kMaxNameBytes);
  h.threads = request_int(j, "threads", 0, 0, 1 << 20);
  h.version = request_string(j, "version", "");
  if (auto tags = request_strings(j, "tags", kMaxTags)) h.tags = checked_tags(std::move(*tags), "tags");
  return h;
}

void to_json(json& j, const Registration& r) {
  // Whole seconds are written as integers, as a person would.
  auto seconds = [](double s) { return s == double(int64_t(s)) ? json(int64_t(s)) : json(s); };
  j = {{"id", r.id}, {"lease_seconds", seconds(r.lease_seconds)}, {"heartbeat_seconds", seconds(r.heartbeat_seconds)},
       {"secret", r.secret}};
}

void from_json(const json& j, Registration& r) {
  r.id = answer_field<std::string>(j, "id", "registration");
  r.lease_seconds = answer_field_or<double>(j, "lease_seconds", "registration", kDefaultLeaseSeconds);
  r.heartbeat_seconds = answer_field_or<double>(j, "heartbeat_seconds", "registration", kDefaultHeartbeatSeconds);
  if (!(r.heartbeat_seconds > 0)) throw ProtocolError("registration: heartbeat_seconds must be positive");
  r.secret = answer_field<std::string>(j, "secret", "registration");
  if (r.secret.empty()) throw ProtocolError("registration: secret must not be empty");
}

void to_json(json& j, const Lease& l) {
  j = {{"lease", l.id},     {"job", l.job},   {"tile", l.tile},
       {"window", json::array({l.window.x0, l.window.y0, l.window.x1, l.window.y1})},
       {"spp", l.spp},      {"seed", l.seed}, {"scene_hash", l.scene_hash}, {"deadline_ms", l.deadline_ms}};
  if (l.resumable) j["resumable"] = true;
  if (l.state_spp) j["state_spp"] = l.state_spp;
}

void from_json(const json& j, Lease& l) {
  l = Lease{};
  l.id = answer_field<std::string>(j, "lease", "lease");
  l.job = answer_field<std::string>(j, "job", "lease");
  l.tile = answer_field<int64_t>(j, "tile", "lease");
  const auto w = answer_field<std::vector<int>>(j, "window", "lease");
  if (w.size() != 4) throw ProtocolError("lease: \"window\" must hold 4 numbers");
  l.window = {w[0], w[1], w[2], w[3]};
  if (l.window.empty()) throw ProtocolError("lease: empty window");
  l.spp = answer_field<uint32_t>(j, "spp", "lease");
  l.seed = answer_field_or<uint64_t>(j, "seed", "lease", 0);
  l.scene_hash = answer_field_or<std::string>(j, "scene_hash", "lease", "");
  l.deadline_ms = answer_field_or<int64_t>(j, "deadline_ms", "lease", 0);
  l.resumable = answer_field_or<bool>(j, "resumable", "lease", false);
  l.state_spp = answer_field_or<uint32_t>(j, "state_spp", "lease", 0);
  if (l.state_spp > l.spp) throw ProtocolError("lease: \"state_spp\" is above \"spp\"");
}

void to_json(json& j, const LeaseRequest& r) {
  j = json::object();
  if (r.known_jobs) j["known_jobs"] = *r.known_jobs;
  if (r.wait_ms > 0) j["wait_ms"] = r.wait_ms;
}

LeaseRequest parse_lease_request(const std::string& body) {
  const json j = parse_request_object(body, {"known_jobs", "wait_ms"}, true);
  return LeaseRequest{request_strings(j, "known_jobs", kMaxKnownJobs), request_int(j, "wait_ms", 0, 0, kMaxLeaseWaitMs)};
}

std::string next_lease_header(const LeaseRequest& r) {
  LeaseRequest sent = r;
  sent.wait_ms = 0;
  return json(sent).dump(-1, ' ', true, json::error_handler_t::replace);
}

std::optional<LeaseRequest> parse_next_lease_header(std::string_view value) {
  if (value.empty()) return std::nullopt;
  LeaseRequest r;
  try {
    r = parse_lease_request(std::string(value));
  } catch (const ProtocolError& e) {
    throw ProtocolError(std::string(kNextLeaseHeader) + ": " + e.what());
  }
  if (r.wait_ms != 0)
    throw ProtocolError(std::string(kNextLeaseHeader) + " must not ask to wait (wait_ms): an upload's answer is never "
                        "held; a worker told of no next lease asks the lease route, which may hold its request");
  return r;
}

void to_json(json& j, const LeaseAnswer& a) {
  const std::string spec = a.spec ? json(*a.spec).dump() : std::string();
  j = json::parse(lease_answer_text(a.lease, a.spec ? &spec : nullptr));
}

void from_json(const json& j, LeaseAnswer& a) {
  a.lease = j.get<Lease>();
  a.spec = optional_message_field<JobSpec>(j, "spec", "lease");
}

std::string lease_answer_text(const Lease& l, const std::string* spec_json) {
  std::string text = json(l).dump();
  if (spec_json) {
    text.pop_back();  // the closing brace of the lease's object, which has keys: the spec goes in as one more
    text += ",\"spec\":";
    text += *spec_json;
    text += '}';
  }
  return text;
}

void to_json(json& j, const HeartbeatReport& h) { j = {{"rays", h.rays}}; }

HeartbeatReport parse_heartbeat_report(const std::string& body) {
  const json j = parse_request_object(body, {"rays"}, true);
  return HeartbeatReport{request_uint(j, "rays", 0)};
}

void to_json(json& j, const HeartbeatAnswer& a) { j = {{"deadline_ms", a.deadline_ms}}; }

void from_json(const json& j, HeartbeatAnswer& a) { a.deadline_ms = answer_field<int64_t>(j, "deadline_ms", "heartbeat answer"); }

UploadStatus upload_status_from_string(const std::string& name) {
  if (const auto s = enum_from_name<UploadStatus>(name, kUploadStatusNames)) return *s;
  throw ProtocolError("unknown upload status '" + name + "'");
}

void to_json(json& j, const ResultAnswer& a) {
  const std::string next = a.next ? json(*a.next).dump() : std::string();
  j = json::parse(result_answer_text(a.status, a.next ? &next : nullptr));
}

void from_json(const json& j, ResultAnswer& a) {
  a.status = upload_status_from_string(answer_field<std::string>(j, "status", "result answer"));
  a.next = optional_message_field<LeaseAnswer>(j, "next", "result answer");
}

std::string result_answer_text(UploadStatus status, const std::string* next_lease_text) {
  std::string text = json{{"status", to_string(status)}}.dump();
  if (next_lease_text) {
    text.pop_back();  // the closing brace: the next lease goes in as one more key
    text += ",\"next\":";
    text += *next_lease_text;
    text += '}';
  }
  return text;
}

void to_json(json& j, const FailReport& f) {
  j = {{"error", f.error}};
  if (!f.log.empty()) j["log"] = f.log;
}

FailReport parse_fail_report(const std::string& body) {
  const json j = parse_request_object(body, {"error", "log"}, true);
  FailReport f{request_bounded_string(j, "error", FailReport{}.error, kMaxFailureErrorBytes), {}};
  if (!j.contains("log")) return f;
  const json& log = j["log"];
  if (!log.is_array() || log.size() > kMaxFailureLogLines)
    throw ProtocolError("'log' must be an array of at most " + std::to_string(kMaxFailureLogLines) + " strings");
  for (const json& line : log) {
    if (!line.is_string() || line.get_ref<const std::string&>().size() > kMaxFailureLogLineBytes)
      throw ProtocolError("'log' lines must be strings of at most " + std::to_string(kMaxFailureLogLineBytes) +
                          " bytes");
    f.log.push_back(line.get<std::string>());
  }
  return f;
}

void to_json(json& j, const FailAnswer& a) { j = {{"status", a.status}}; }
void from_json(const json& j, FailAnswer& a) { a.status = answer_field<std::string>(j, "status", "fail answer"); }

void to_json(json& j, const ReleaseAnswer& a) { j = {{"status", a.status}}; }
void from_json(const json& j, ReleaseAnswer& a) { a.status = answer_field<std::string>(j, "status", "release answer"); }

DiskState disk_state_from_string(const std::string& name) {
  if (const auto s = enum_from_name<DiskState>(name, kDiskStateNames)) return *s;
  throw ProtocolError("unknown disk state '" + name + "'");
}

void to_json(json& j, const HealthAnswer& a) {
  j = {{"status", a.status}, {"disk", to_string(a.disk)}, {"disk_free_bytes", a.disk_free_bytes},
       {"min_free_disk", a.min_free_disk}};
}

void from_json(const json& j, HealthAnswer& a) {
  a.status = answer_field<std::string>(j, "status", "health answer");
  // A coordinator without the disk keys says only "ok".
  a.disk = disk_state_from_string(answer_field_or<std::string>(j, "disk", "health answer", "ok"));
  a.disk_free_bytes = answer_field_or<uint64_t>(j, "disk_free_bytes", "health answer", 0);
  a.min_free_disk = answer_field_or<uint64_t>(j, "min_free_disk", "health answer", 0);
}

void to_json(json& j, const BlobPutAnswer& a) { j = {{"sha256", a.sha256}, {"size", a.size}}; }

void from_json(const json& j, BlobPutAnswer& a) {
  a.sha256 = answer_field<std::string>(j, "sha256", "blob upload answer");
  a.size = answer_field<uint64_t>(j, "size", "blob upload answer");
}

void to_json(json& j, const ErrorAnswer& a) { j = {{"error", a.error}}; }
void from_json(const json& j, ErrorAnswer& a) { a.error = answer_field<std::string>(j, "error", "error answer"); }

std::string error_text(const ErrorAnswer& a) { return json(a).dump(-1, ' ', false, json::error_handler_t::replace); }

void to_json(json& j, const Capabilities& c) { j = {{"tokens_required", c.tokens_required}, {"endpoints", c.endpoints}}; }

void from_json(const json& j, Capabilities& c) {
  c.tokens_required = answer_field<bool>(j, "tokens_required", "capabilities");
  c.endpoints = answer_field<std::map<std::string, bool>>(j, "endpoints", "capabilities");
}

Capabilities capabilities(bool tokens_required) {
  Capabilities c{tokens_required, {}};
  for (const RouteSpec& r : route_table())
    for (const MethodSpec& m : r.methods)
      if (!m.capability.empty()) c.endpoints[std::string(m.capability)] = true;
  return c;
}

void parse_empty_request(const std::string& body) { parse_request_object(body, {}, true); }

void to_json(json& j, const JobList& l) {
  j = {{"jobs", l.jobs}, {"next", nullptr}};
  if (l.next) j["next"] = *l.next;
}

void from_json(const json& j, JobList& l) {
  l.jobs = answer_field<std::vector<JobStatus>>(j, "jobs", "job list");
  const std::string next = answer_field_or<std::string>(j, "next", "job list", "");
  if (!next.empty()) l.next = next;
}

void to_json(json& j, const FrameList& l) {
  j = {{"frames", l.frames}, {"next", nullptr}};
  if (l.next) j["next"] = *l.next;
}

void from_json(const json& j, FrameList& l) {
  l.frames = answer_field<std::vector<JobStatus>>(j, "frames", "frame list");
  if (j.contains("next") && !j["next"].is_null()) l.next = answer_field<int64_t>(j, "next", "frame list");
}

void to_json(json& j, const PurgeAnswer& a) { j = {{"id", a.id}, {"purged", true}, {"was", to_string(a.was)}}; }

void from_json(const json& j, PurgeAnswer& a) {
  a.id = answer_field<std::string>(j, "id", "purge answer");
  try {
    a.was = job_state_from_string(answer_field<std::string>(j, "was", "purge answer"));
  } catch (const std::invalid_argument& e) {
    throw ProtocolError(std::string("purge answer: \"was\": ") + e.what());
  }
}

}  // namespace tessera::protocol
