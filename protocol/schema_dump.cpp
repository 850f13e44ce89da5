// Prints the JSON form of every protocol type that goes on the wire, keyed by the name of its schema in
// docs/openapi.yaml: {"Schema": {"full": <a value with every optional field set and every list non-empty>,
// "minimal": <a default value>}}. tests/openapi/check_types.py compares both with the document's properties and
// required fields, so that the document and the types cannot drift apart.
#include "protocol/events.h"
#include "protocol/job.h"
#include "protocol/messages.h"
#include "protocol/tile.h"
#include "protocol/worker.h"

#include <cstdio>

using namespace tessera::protocol;
using nlohmann::json;

namespace {

SamplingSettings full_sampling() {
  SamplingSettings s;
  s.spp = 16;
  s.seed = 3;
  s.integrator = "direct";
  s.target_error = 0.02;
  s.error_floor = 0.5;
  s.replicates = 4;
  s.area_sampling = "area";
  s.env_sampling = "cosine";
  s.bvh = "median";
  return s;
}

// A default T with `set` applied.
template <class T, class Set>
T with(Set set) {
  T v;
  set(v);
  return v;
}

JobStatus full_job() {
  return with<JobStatus>([](JobStatus& s) {
    s.id = "j-1"; s.started_ms = 1; s.finished_ms = 2; s.error = "e"; s.workers = {"w-1"};
  });
}

WorkerInfo full_worker() {
  return with<WorkerInfo>([](WorkerInfo& w) { w.id = "w-1"; w.job = "j-1"; w.tile = 0; w.blocklisted_for = {"j-2"}; });
}

TileInfo full_tile() {
  return with<TileInfo>([](TileInfo& t) {
    t.worker = "w-1"; t.worker_name = "n"; t.render_seconds = 1.0; t.rendered_by = "w-1"; t.rendered_by_name = "n";
    t.failures = {TileFailure{"w-2", "m", "e", {"line"}}};
  });
}

}  // namespace

int main() {
  json out = json::object();
  const auto add = [&](const char* schema, const json& full, const json& minimal) {
    out[schema] = {{"full", full}, {"minimal", minimal}};
  };
  add("Sampling", full_sampling(), SamplingSettings{});
  JobSubmission sub;
  sub.sampling = full_sampling();
  sub.tile_timeout_seconds = kDefaultTileTimeoutSeconds + 1;
  sub.resumable = true;
  add("JobSubmission", sub, JobSubmission{});
  JobPatch patch;
  patch.priority = 1;
  patch.spp = 2;
  add("JobPatch", patch, JobPatch{});
  add("SubmitAnswer", SubmitAnswer{"j-1", {"w"}}, SubmitAnswer{});
  JobSpec spec;
  spec.sampling = full_sampling();
  spec.resumable = true;
  add("JobSpec", spec, JobSpec{});
  add("BlobQuery", BlobQuery{{"a"}}, BlobQuery{});
  add("BlobQueryAnswer", BlobQueryAnswer{{"a"}}, BlobQueryAnswer{});
  add("WorkerHello", WorkerHello{}, WorkerHello{});
  add("Registration", Registration{}, Registration{});
  Lease lease;
  lease.resumable = true;
  lease.state_spp = 4;
  // The lease answer: the lease's keys, and its job's spec when the worker does not hold it.
  const std::string spec_text = json(spec).dump();
  add("Lease", json::parse(lease_answer_text(lease, &spec_text)), json::parse(lease_answer_text(Lease{}, nullptr)));
  LeaseRequest request;
  request.known_jobs = std::vector<std::string>{"j-1"};
  request.wait_ms = 5;
  add("LeaseRequest", request, LeaseRequest{});
  add("HeartbeatReport", HeartbeatReport{}, HeartbeatReport{});
  add("HeartbeatAnswer", HeartbeatAnswer{}, HeartbeatAnswer{});
  add("FailReport", FailReport{"e", {"line"}}, FailReport{});
  add("Health", HealthAnswer{}, HealthAnswer{});
  add("BlobStored", BlobPutAnswer{}, BlobPutAnswer{});
  add("Error", ErrorAnswer{"e"}, ErrorAnswer{});
  add("Job", full_job(), JobStatus{});
  add("JobList", JobList{{full_job()}, "j-0"}, JobList{});
  add("PurgeAnswer", PurgeAnswer{}, PurgeAnswer{});
  add("Worker", full_worker(), WorkerInfo{});
  add("WorkerList", WorkerList{{full_worker()}}, WorkerList{});
  add("TileFailure", TileFailure{"w-1", "n", "e", {"line"}}, TileFailure{});
  add("Tile", full_tile(), TileInfo{});
  add("TileList", TileList{"j-1", {full_tile()}}, TileList{});
  add("TileEvent", TileEvent{"j-1", 0, "w-1", "l-1", "e"}, TileEvent{});
  add("WorkerEvent", WorkerEvent{"registered", full_worker()}, WorkerEvent{});
  // The three status answers share one schema, "Status" (and the upload's names its UploadStatus).
  add("Status", ResultAnswer{}, ResultAnswer{});
  std::puts(out.dump(1).c_str());
}
