#include "protocol/messages.h"
#include "protocol/routes.h"
#include "protocol/tile.h"
#include "protocol/worker.h"

#include <gtest/gtest.h>

namespace tessera::protocol {
namespace {

using nlohmann::json;

TEST(Routes, BuildersAndTheMatcherAgree) {
  for (const RouteSpec& r : route_table()) {
    const std::string target = path(r.endpoint, "x-1", "7");
    const RouteMatch m = match_route(target + "?q=1");
    ASSERT_NE(m.route, nullptr) << target;
    EXPECT_EQ(m.route->endpoint, r.endpoint) << target;
    if (r.pattern.find('{') != std::string_view::npos) {
      EXPECT_EQ(m.param, "x-1");
    }
  }
  EXPECT_EQ(routes::lease_result("l-3"), "/v1/leases/l-3/result");
  EXPECT_EQ(routes::job_tile_requeue("j-2", 5), "/v1/jobs/j-2/tiles/5/requeue");
  const RouteMatch requeue = match_route("/v1/jobs/j-2/tiles/5/requeue");
  ASSERT_NE(requeue.route, nullptr);
  EXPECT_EQ(requeue.route->endpoint, Endpoint::job_tile_requeue);
  EXPECT_EQ(requeue.param, "j-2");
  EXPECT_EQ(requeue.param2, "5");
  EXPECT_EQ(match_route("/v1/jobs/j-2/tiles/5").route, nullptr);
  EXPECT_EQ(match_route("/v1/jobs/").route, nullptr);
  EXPECT_EQ(match_route("//v1/jobs").route, nullptr);
  EXPECT_EQ(match_route("v1/jobs").route, nullptr);
  EXPECT_EQ(match_route("/v1/jobs/a/b").route, nullptr);
}

TEST(Messages, ParsesALease) {
  const auto l = json::parse(R"({"lease": "l-1", "job": "j-2", "tile": 7, "window": [64, 0, 128, 64], "spp": 32,
                                 "seed": 5, "scene_hash": "ab", "deadline_ms": 9})").get<Lease>();
  EXPECT_EQ(l.id, "l-1");
  EXPECT_EQ(l.job, "j-2");
  EXPECT_EQ(l.tile, 7);
  EXPECT_EQ(l.window, (PixelWindow{64, 0, 128, 64}));
  EXPECT_EQ(l.spp, 32u);
  EXPECT_EQ(l.seed, 5u);
  EXPECT_EQ(json(l).get<Lease>().deadline_ms, 9);
  // An ordinary job's lease carries no resumable keys (its answer is what it was before resumable jobs existed).
  EXPECT_FALSE(json(l).contains("resumable"));
  EXPECT_FALSE(json(l).contains("state_spp"));
  Lease r = l;
  r.resumable = true;
  r.state_spp = 8;
  const Lease back = json(r).get<Lease>();
  EXPECT_TRUE(back.resumable);
  EXPECT_EQ(back.state_spp, 8u);
  r.state_spp = 64;
  EXPECT_THROW((void)json(r).get<Lease>(), ProtocolError);  // a state above the lease's spp
}

TEST(Messages, ABlobQueryNamesValidHashesWithinItsLimit) {
  const std::string a(64, 'a'), b(64, '0');
  EXPECT_EQ(parse_blob_query(json(BlobQuery{{a, b}}).dump()).sha256, (std::vector<std::string>{a, b}));
  EXPECT_TRUE(parse_blob_query(R"({"sha256": []})").sha256.empty());
  const auto refused = [](const std::string& body, const std::string& said) {
    try {
      parse_blob_query(body);
      ADD_FAILURE() << body << " was taken";
    } catch (const ProtocolError& e) {
      EXPECT_NE(std::string(e.what()).find(said), std::string::npos) << e.what();
    }
  };
  refused("", "");                                 // a query needs its list
  refused(R"({"sha256": "aa"})", "must be an array");
  refused(json{{"sha256", {a, std::string(64, 'A')}}}.dump(), "\"sha256\"[1] is not 64 lowercase hex digits");
  refused(json{{"sha256", {a.substr(1)}}}.dump(), "\"sha256\"[0]");
  refused(json{{"sha256", {a}}, {"more", 1}}.dump(), "more");
  refused(json{{"sha256", std::vector<std::string>(kMaxBlobQuery + 1, a)}}.dump(), "at most 4096");
  EXPECT_EQ(parse_blob_query(json{{"sha256", std::vector<std::string>(kMaxBlobQuery, a)}}.dump()).sha256.size(),
            kMaxBlobQuery);
  const BlobQueryAnswer back = parse_answer<BlobQueryAnswer>(json(BlobQueryAnswer{{b}}).dump(), "blob query");
  EXPECT_EQ(back.missing, std::vector<std::string>{b});
}

TEST(Messages, ALeaseRequestNamesKnownJobsAndItsAnswerMayCarryTheSpec) {
  // No body, {} and an explicit absence all ask for a bare lease; a list (even empty) asks for the spec of others.
  EXPECT_FALSE(parse_lease_request("").known_jobs);
  EXPECT_FALSE(parse_lease_request("{}").known_jobs);
  const LeaseRequest r = parse_lease_request(json(LeaseRequest{std::vector<std::string>{"j-1", "j-2"}}).dump());
  ASSERT_TRUE(r.known_jobs);
  EXPECT_EQ(*r.known_jobs, (std::vector<std::string>{"j-1", "j-2"}));
  EXPECT_EQ(parse_lease_request(R"({"known_jobs": []})").known_jobs, std::vector<std::string>{});
  EXPECT_EQ(json(LeaseRequest{}).dump(), "{}");
  // Strict, as every request: unknown keys, wrong types and too long a list are refused with the reason.
  EXPECT_THROW(parse_lease_request(R"({"known": []})"), ProtocolError);
  EXPECT_THROW(parse_lease_request(R"({"known_jobs": "j-1"})"), ProtocolError);
  EXPECT_THROW(parse_lease_request(R"({"known_jobs": [1]})"), ProtocolError);
  EXPECT_THROW(parse_lease_request("[]"), ProtocolError);
  const std::vector<std::string> many(kMaxKnownJobs + 1, "j-1");
  try {
    parse_lease_request(json{{"known_jobs", many}}.dump());
    ADD_FAILURE() << "a list of " << many.size() << " jobs was taken";
  } catch (const ProtocolError& e) {
    EXPECT_NE(std::string(e.what()).find("at most 64"), std::string::npos) << e.what();
  }
  EXPECT_NO_THROW(parse_lease_request(json{{"known_jobs", std::vector<std::string>(kMaxKnownJobs, "j-1")}}.dump()));
  // How long the coordinator may hold it for work: 0 (answer at once) unless asked, up to kMaxLeaseWaitMs.
  EXPECT_EQ(parse_lease_request("{}").wait_ms, 0);
  EXPECT_EQ(parse_lease_request(R"({"wait_ms": 2000})").wait_ms, 2000);
  EXPECT_EQ(parse_lease_request(json(LeaseRequest{std::nullopt, 1500}).dump()).wait_ms, 1500);
  EXPECT_EQ(parse_lease_request(json{{"wait_ms", kMaxLeaseWaitMs}}.dump()).wait_ms, kMaxLeaseWaitMs);
  EXPECT_THROW(parse_lease_request(json{{"wait_ms", kMaxLeaseWaitMs + 1}}.dump()), ProtocolError);
  EXPECT_THROW(parse_lease_request(R"({"wait_ms": -1})"), ProtocolError);
  EXPECT_THROW(parse_lease_request(R"({"wait_ms": 1.5})"), ProtocolError);
  EXPECT_THROW(parse_lease_request(R"({"wait_ms": "2000"})"), ProtocolError);

  // The answer: the lease's keys, and "spec" with the spec's own text when one is sent.
  Lease l;
  l.id = "l-1";
  l.job = "j-3";
  l.window = {0, 0, 16, 16};
  l.spp = 4;
  JobSpec spec;
  spec.scene = {{"camera", {{"fov", 40}}}};
  spec.assets = {{"tex.exr", std::string(64, 'a')}};
  spec.sampling.spp = 4;
  spec.width = 32;
  spec.height = 16;
  const std::string spec_text = json(spec).dump();
  const LeaseAnswer bare = parse_answer<LeaseAnswer>(lease_answer_text(l, nullptr), "lease");
  EXPECT_EQ(bare.lease.id, "l-1");
  EXPECT_FALSE(bare.spec);
  EXPECT_EQ(lease_answer_text(l, nullptr), json(l).dump());  // a bare answer is the lease as it always was
  const LeaseAnswer with = parse_answer<LeaseAnswer>(lease_answer_text(l, &spec_text), "lease");
  EXPECT_EQ(with.lease.job, "j-3");
  EXPECT_EQ(with.lease.window, (PixelWindow{0, 0, 16, 16}));
  ASSERT_TRUE(with.spec);
  EXPECT_EQ(json(*with.spec), json(spec));
  EXPECT_EQ(json::parse(lease_answer_text(l, &spec_text))["spec"], json::parse(spec_text));
  // A lease reader that knows nothing of specs still reads the answer (answers are read tolerantly).
  EXPECT_EQ(parse_answer<Lease>(lease_answer_text(l, &spec_text), "lease").id, "l-1");
  // A broken spec is named.
  try {
    (void)parse_answer<LeaseAnswer>(R"({"lease":"l-1","job":"j","tile":0,"window":[0,0,1,1],"spp":1,"spec":{}})", "lease");
    ADD_FAILURE() << "a spec without a scene was taken";
  } catch (const ProtocolError& e) {
    EXPECT_NE(std::string(e.what()).find("\"spec\""), std::string::npos) << e.what();
  }
}

TEST(Messages, ASpecSaysWhetherTheJobIsResumable) {
  JobSpec spec;
  spec.sampling.spp = 4;
  spec.width = spec.height = 8;
  EXPECT_FALSE(json(spec).contains("resumable"));
  EXPECT_FALSE(json(spec).get<JobSpec>().resumable);
  spec.resumable = true;
  EXPECT_TRUE(json(spec).get<JobSpec>().resumable);
}

TEST(Messages, NamesTheFieldThatIsWrong) {
  try {
    (void)json::parse(R"({"lease": "l-1", "job": "j-2", "tile": 7, "window": [1, 2, 3], "spp": 1})").get<Lease>();
    FAIL();
  } catch (const ProtocolError& e) {
    EXPECT_STREQ(e.what(), "lease: \"window\" must hold 4 numbers");
  }
  try {
    (void)json::parse(R"({"id": "j-1"})").get<JobStatus>();
    FAIL();
  } catch (const ProtocolError& e) {
    EXPECT_STREQ(e.what(), "job: missing \"state\"");
  }
  EXPECT_THROW(parse_body("<html>", "lease"), ProtocolError);
}

TEST(Messages, JobStatusRoundTrips) {
  JobStatus s;
  s.id = "j-1";
  s.state = JobState::running;
  s.params.width = 8;
  s.params.height = 4;
  s.tiles = {4, 1, 2, 1};
  s.started_ms = 10;
  s.render_seconds = 1.5;
  const auto back = json(s).get<JobStatus>();
  EXPECT_EQ(back.tiles.total, 4);
  EXPECT_EQ(back.tiles.done, 1);
  EXPECT_EQ(back.params.width, 8);
  EXPECT_FALSE(back.finished());
  EXPECT_FALSE(back.error);
  EXPECT_EQ(back.started_ms, 10);
  EXPECT_FALSE(back.finished_ms);
}

TEST(Messages, ParsesAJobWithNullError) {
  const auto s = json::parse(R"({"id": "j-1", "state": "running", "width": 8, "height": 4, "tiles": {"total": 4,
      "done": 1, "leased": 2, "pending": 1}, "render_seconds": 1.5, "error": null, "finished_ms": null})").get<JobStatus>();
  EXPECT_EQ(s.tiles.total, 4);
  EXPECT_EQ(s.tiles.done, 1);
  EXPECT_FALSE(s.finished());
  EXPECT_FALSE(s.error);
}

TEST(Messages, SubmissionRefusesUnknownKeysAndBadSettings) {
  auto error_of = [](const std::string& body) {
    try {
      parse_job_submission(body);
    } catch (const ProtocolError& e) {
      return std::string(e.what());
    }
    return std::string("(accepted)");
  };
  EXPECT_EQ(error_of(R"({"scene": {}, "spps": 4})").rfind("unknown key 'spps' (known keys: scene, assets, frames, frame_order, spp", 0), 0u);
  EXPECT_EQ(error_of(R"({"scene": {}, "min_spp": 4})"), "'min_spp' and 'max_spp' apply only with 'target_error'");
  EXPECT_EQ(error_of(R"({"scene": {}, "bvh": "octree"})"), "'bvh' must be one of sah, median (got \"octree\")");
  EXPECT_EQ(error_of(R"({"scene": {}, "replicates": 99})"), "'replicates' must be an integer in 1..16 (got 99)");
  EXPECT_EQ(error_of(""), "request body is empty; expected a JSON object");
  EXPECT_EQ(error_of(R"({"scene": {}, "resumable": 1})"), "'resumable' must be true or false (got 1)");
  EXPECT_EQ(error_of(R"({"scene": {}, "resumable": true, "target_error": 0.1})").rfind("'resumable' needs a fixed spp", 0), 0u);
  EXPECT_TRUE(parse_job_submission(R"({"scene": {}, "resumable": true})").resumable);
}

TEST(Messages, AJobPatchCarriesAPriorityAndOrAnSpp) {
  EXPECT_EQ(parse_job_patch(R"({"priority": -7})").priority, -7);
  EXPECT_FALSE(parse_job_patch(R"({"priority": -7})").spp);
  EXPECT_EQ(parse_job_patch(nlohmann::json(JobPatch{12, std::nullopt}).dump()).priority, 12);
  const JobPatch both = parse_job_patch(nlohmann::json(JobPatch{3, 256}).dump());
  EXPECT_EQ(both.priority, 3);
  EXPECT_EQ(both.spp, 256u);
  EXPECT_EQ(parse_job_patch(R"({"spp": 64})").spp, 64u);
  EXPECT_FALSE(parse_job_patch(R"({"spp": 64})").priority);
  EXPECT_THROW(parse_job_patch(R"({"spp": 0})"), ProtocolError);
  EXPECT_THROW(parse_job_patch(R"({"spp": 1.5})"), ProtocolError);
  EXPECT_THROW(parse_job_patch(R"({"priority": 1, "name": "x"})"), ProtocolError);
  EXPECT_THROW(parse_job_patch("{}"), ProtocolError);
  EXPECT_THROW(parse_job_patch(""), ProtocolError);
  EXPECT_THROW(parse_job_patch(R"({"priority": "high"})"), ProtocolError);
  EXPECT_THROW(parse_job_patch(R"({"priority": 2147483648})"), ProtocolError);
}

TEST(Messages, AFailReportCarriesBoundedLogLines) {
  const FailReport f = parse_fail_report(R"({"error": "boom", "log": ["a", "b"]})");
  EXPECT_EQ(f.error, "boom");
  EXPECT_EQ(f.log, (std::vector<std::string>{"a", "b"}));
  EXPECT_TRUE(parse_fail_report(R"({"error": "boom"})").log.empty());
  EXPECT_EQ(json(f), json::parse(R"({"error": "boom", "log": ["a", "b"]})"));
  EXPECT_THROW(parse_fail_report(R"({"error": "x", "lines": []})"), ProtocolError);  // unknown keys are refused
  EXPECT_THROW(parse_fail_report(R"({"log": "one line"})"), ProtocolError);
  EXPECT_THROW(parse_fail_report(R"({"log": [1]})"), ProtocolError);
  EXPECT_THROW(parse_fail_report(json{{"log", std::vector<std::string>(kMaxFailureLogLines + 1, "x")}}.dump()), ProtocolError);
  EXPECT_THROW(parse_fail_report(json{{"log", {std::string(kMaxFailureLogLineBytes + 1, 'x')}}}.dump()), ProtocolError);
}

TEST(Messages, TileListRoundTrips) {
  TileList l{"j-1", {}};
  TileInfo t;
  t.index = 3;
  t.window = {64, 0, 128, 64};
  t.state = "done";
  t.attempts = 2;
  t.render_seconds = 1.25;
  t.rays = 99;
  t.failures = {{"w-1", "alpha", "boom", {"x", "y"}}};
  l.tiles.push_back(t);
  TileInfo leased;
  leased.state = "leased";
  leased.worker = "w-2";
  leased.worker_name = "beta";
  l.tiles.push_back(leased);
  const TileList back = json(l).get<TileList>();
  ASSERT_EQ(back.tiles.size(), 2u);
  EXPECT_EQ(back.job, "j-1");
  EXPECT_EQ(back.tiles[0].window, t.window);
  EXPECT_EQ(back.tiles[0].render_seconds, 1.25);
  EXPECT_EQ(back.tiles[0].failures[0].log, t.failures[0].log);
  EXPECT_EQ(back.tiles[1].worker, "w-2");
  EXPECT_TRUE(json(l)["tiles"][1]["render_seconds"].is_null());
}

TEST(Messages, WorkerListRoundTrips) {
  WorkerInfo w;
  w.id = "w-1";
  w.name = "host";
  w.state = WorkerState::rendering;
  w.job = "j-2";
  w.tile = 7;
  w.threads = 8;
  w.tiles_done = 3;
  w.last_seen_ms = 1234;
  w.blocklisted_for = {"j-3"};
  WorkerInfo idle;
  idle.id = "w-2";
  const WorkerList back = parse_answer<WorkerList>(nlohmann::json(WorkerList{{w, idle}}).dump(), "list");
  ASSERT_EQ(back.workers.size(), 2u);
  const WorkerInfo& b = back.workers[0];
  EXPECT_EQ(b.state, WorkerState::rendering);
  EXPECT_EQ(b.job, "j-2");
  EXPECT_EQ(b.tile, 7);
  EXPECT_EQ(b.blocklisted_for, std::vector<std::string>{"j-3"});
  EXPECT_EQ(b.tiles_done, 3);
  EXPECT_FALSE(back.workers[1].job);
  EXPECT_FALSE(back.workers[1].tile);
  EXPECT_THROW(parse_answer<WorkerList>(R"({"workers": [{"id": "w", "state": "asleep"}]})", "list"), ProtocolError);
}

TEST(Messages, ASubmissionsSettingsReachTheSpecUnchanged) {
  const JobSubmission sub = parse_job_submission(
      R"({"scene": {"a": 1}, "spp": 8, "seed": 3, "target_error": 0.1, "max_spp": 64, "error_floor": 0.5,
          "replicates": 4, "area_sampling": "area", "env_sampling": "cosine", "bvh": "median"})");
  JobSpec spec{sub.scene, sub.assets, sub.sampling, 16, 8, sub.tile_size};
  const auto back = json(spec).get<JobSpec>();
  EXPECT_EQ(json(back), json(spec));
  EXPECT_EQ(back.sampling.replicates, 4u);
  EXPECT_EQ(back.sampling.bvh, "median");
  const LoadOptions lo = back.sampling.load_options();
  EXPECT_EQ(lo.spp, 8u);
  EXPECT_EQ(lo.bvh, SplitMethod::kMedian);
  RenderOptions ro;
  back.sampling.apply_to(ro);
  EXPECT_EQ(ro.max_spp, 64u);
  EXPECT_FLOAT_EQ(ro.error_floor, 0.5f);
  EXPECT_EQ(ro.seed, 3u);
}


// Texts the coordinator stores are bounded: a failure text, a worker's name and a job's name longer than their limit
// are cut at a character boundary and marked as cut, never stored whole.
TEST(Messages, StoredTextsAreCutAndMarkedBeyondTheirBound) {
  const std::string huge(15 << 20, 'x');
  const FailReport f = parse_fail_report(nlohmann::json{{"error", huge}}.dump());
  EXPECT_EQ(f.error, std::string(kMaxFailureErrorBytes, 'x') + " [cut from " + std::to_string(huge.size()) + " bytes]");
  const WorkerHello h = parse_worker_hello(nlohmann::json{{"name", std::string(1 << 20, 'w')}}.dump());
  EXPECT_EQ(h.name.substr(0, kMaxNameBytes), std::string(kMaxNameBytes, 'w'));
  EXPECT_EQ(h.name.substr(kMaxNameBytes), " [cut from 1048576 bytes]");
  EXPECT_EQ(parse_worker_hello(R"({"name":"render-1"})").name, "render-1");  // within the bound: unchanged
  // A cut never splits a UTF-8 character: 'é' is two bytes, and 255 of 256 bytes end inside the 128th.
  std::string accented;
  for (int i = 0; i < 200; ++i) accented += "\xc3\xa9";
  const std::string cut = bounded_text(accented, kMaxNameBytes - 1);
  EXPECT_EQ(cut.substr(0, cut.find(' ')).size(), 254u);
  EXPECT_EQ(cut.substr(cut.find(' ')), " [cut from 400 bytes]");
}

}  // namespace
}  // namespace tessera::protocol
