#include "protocol/events.h"
#include "protocol/messages.h"
#include "protocol/routes.h"
#include "protocol/sequence.h"
#include "protocol/tile.h"
#include "protocol/tile_log.h"
#include "protocol/worker.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <iterator>
#include <string_view>

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

TEST(Messages, AnUploadMayAskForTheNextLeaseAndItsAnswerCarriesIt) {
  // The header is a lease request's JSON in ASCII, read back as the lease route reads its body; no header, no ask.
  EXPECT_FALSE(parse_next_lease_header(""));
  const LeaseRequest asked{std::vector<std::string>{"j-1", "j-\u00e9"}, 0};
  const std::string value = next_lease_header(asked);
  EXPECT_TRUE(std::all_of(value.begin(), value.end(), [](char c) { return c >= 0x20 && c < 0x7f; })) << value;
  const std::optional<LeaseRequest> back = parse_next_lease_header(value);
  ASSERT_TRUE(back);
  EXPECT_EQ(back->known_jobs, asked.known_jobs);
  EXPECT_EQ(back->wait_ms, 0);
  const std::optional<LeaseRequest> bare = parse_next_lease_header(next_lease_header(LeaseRequest{}));
  ASSERT_TRUE(bare);
  EXPECT_FALSE(bare->known_jobs);
  // An upload's answer is never held: a wait is not sent, and refused when asked for; bad values name the header.
  EXPECT_EQ(next_lease_header(LeaseRequest{std::nullopt, 2000}), "{}");
  for (const char* bad : {R"({"wait_ms": 100})", R"({"known_jobs": "j-1"})", "[]", "yes"}) {
    try {
      (void)parse_next_lease_header(bad);
      ADD_FAILURE() << bad << " was taken";
    } catch (const ProtocolError& e) {
      EXPECT_NE(std::string(e.what()).find(kNextLeaseHeader), std::string::npos) << e.what();
    }
  }

  // The answer: the status alone as before, or with "next", the lease route's answer (spec included) as it is.
  EXPECT_EQ(result_answer_text(UploadStatus::accepted, nullptr), json(ResultAnswer{}).dump());
  EXPECT_EQ(result_answer_text(UploadStatus::duplicate, nullptr), R"({"status":"duplicate"})");
  Lease l;
  l.id = "l-2";
  l.job = "j-3";
  l.tile = 5;
  l.window = {16, 0, 32, 16};
  l.spp = 4;
  JobSpec spec;
  spec.scene = {{"camera", {{"fov", 40}}}};
  spec.sampling.spp = 4;
  spec.width = 32;
  spec.height = 16;
  const std::string spec_text = json(spec).dump();
  const std::string lease_text = lease_answer_text(l, &spec_text);
  const std::string text = result_answer_text(UploadStatus::accepted, &lease_text);
  EXPECT_EQ(json::parse(text)["next"], json::parse(lease_text));
  const ResultAnswer a = parse_answer<ResultAnswer>(text, "result");
  EXPECT_EQ(a.status, UploadStatus::accepted);
  ASSERT_TRUE(a.next);
  EXPECT_EQ(a.next->lease.id, "l-2");
  EXPECT_EQ(a.next->lease.tile, 5);
  ASSERT_TRUE(a.next->spec);
  EXPECT_EQ(json(*a.next->spec), json(spec));
  EXPECT_EQ(json(a), json::parse(text));  // the struct writes what the coordinator sends
  EXPECT_FALSE(parse_answer<ResultAnswer>(R"({"status":"accepted","next":null})", "result").next);
  EXPECT_FALSE(parse_answer<ResultAnswer>(R"({"status":"accepted"})", "result").next);  // today's answers
  try {
    (void)parse_answer<ResultAnswer>(R"({"status":"accepted","next":{"lease":"l-1"}})", "result");
    ADD_FAILURE() << "a next lease without a job was taken";
  } catch (const ProtocolError& e) {
    EXPECT_NE(std::string(e.what()).find("\"next\""), std::string::npos) << e.what();
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
  EXPECT_EQ(error_of(R"({"scene": {}, "layers": "albedo"})").rfind("'layers' must be an array of layer names", 0), 0u);
  EXPECT_NE(error_of(R"({"scene": {}, "layers": ["albedo", "albedo"]})").find("\"albedo\" is named twice"),
            std::string::npos);
  EXPECT_NE(error_of(R"({"scene": {}, "layers": ["beauty"]})").find("(got \"beauty\")"), std::string::npos);
  const JobSubmission layered = parse_job_submission(R"({"scene": {}, "layers": ["normal", "crypto_object"]})");
  EXPECT_EQ(layers_to_string(layered.sampling.layers), "normal,crypto_object");
  EXPECT_EQ(nlohmann::json(layered.sampling)["layers"], nlohmann::json::parse(R"(["normal", "crypto_object"])"));
  EXPECT_EQ(layered.sampling.metadata().at("tessera:layers"), "normal,crypto_object");
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

TEST(TileLog, AnUploadsLogTravelsAsABoundedAsciiHeader) {
  EXPECT_EQ(tile_log_header({}), "");
  EXPECT_TRUE(parse_tile_log_header("").empty());  // an upload without the header: no log
  const std::vector<std::string> lines{"leased window [0,8)x[0,8)", "rendered in 0.5s \"quoted\" \xc3\xa9t\xc3\xa9"};
  const std::string header = tile_log_header(lines);
  EXPECT_TRUE(std::all_of(header.begin(), header.end(), [](char c) { return c >= 0x20 && c < 0x7f; })) << header;
  EXPECT_EQ(parse_tile_log_header(header), lines);
  // The worker's side keeps within the bounds: the last lines, each cut (never inside a character), the oldest
  // dropped until the header fits.
  std::vector<std::string> many;
  for (int i = 0; i < 30; ++i) many.push_back("line " + std::to_string(i));
  const auto last = parse_tile_log_header(tile_log_header(many));
  ASSERT_EQ(last.size(), kMaxTileLogLines);
  EXPECT_EQ(last.front(), "line 10");
  std::string accents;
  while (accents.size() < 2 * kMaxTileLogLineBytes) accents += "\xc3\xa9";
  const auto cut = parse_tile_log_header(tile_log_header({"x" + accents}));
  ASSERT_EQ(cut.size(), 1u);
  EXPECT_EQ(cut[0].size(), kMaxTileLogLineBytes - 1);  // "x" and whole two-byte characters
  const std::vector<std::string> wide(kMaxTileLogLines, accents);  // each escaped to 6 bytes a character
  const std::string fitted = tile_log_header(wide);
  EXPECT_LE(fitted.size(), kMaxTileLogHeaderBytes);
  EXPECT_LT(parse_tile_log_header(fitted).size(), kMaxTileLogLines);
  EXPECT_FALSE(parse_tile_log_header(fitted).empty());
  // The coordinator's side refuses what is beyond them.
  EXPECT_THROW(parse_tile_log_header(std::string(kMaxTileLogHeaderBytes + 1, ' ')), ProtocolError);
  EXPECT_THROW(parse_tile_log_header("not json"), ProtocolError);
  EXPECT_THROW(parse_tile_log_header(R"({"log": []})"), ProtocolError);
  EXPECT_THROW(parse_tile_log_header("[1]"), ProtocolError);
  EXPECT_THROW(parse_tile_log_header(json(std::vector<std::string>(kMaxTileLogLines + 1, "x")).dump()), ProtocolError);
  EXPECT_THROW(parse_tile_log_header(json({std::string(kMaxTileLogLineBytes + 1, 'x')}).dump()), ProtocolError);
}

TEST(Messages, TileListRoundTrips) {
  TileList l{"j-1", {}, 5};
  TileInfo t;
  t.index = 3;
  t.window = {64, 0, 128, 64};
  t.state = "done";
  t.attempts = 2;
  t.render_seconds = 1.25;
  t.rays = 99;
  t.failures = {{"w-1", "alpha", "boom", {"x", "y"}}};
  t.log = {"rendered in 1.25s"};
  t.log_not_kept = true;
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
  EXPECT_EQ(back.tiles[0].log, t.log);
  EXPECT_TRUE(back.tiles[0].log_not_kept);
  EXPECT_EQ(back.logs_not_kept, 5);
  EXPECT_EQ(back.tiles[1].worker, "w-2");
  // An older coordinator's answer, without the done tiles' logs.
  const TileList old = json::parse(R"({"job": "j-1", "tiles": [{"index": 0, "state": "done"}]})").get<TileList>();
  EXPECT_TRUE(old.tiles[0].log.empty());
  EXPECT_EQ(old.logs_not_kept, 0);
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


// ---- Sequences: a submission of frames, a retry of chosen frames, and the answers that carry frames.

// The sentence a submission is refused with, or "(accepted)".
std::string submission_refusal(const std::string& body) {
  try {
    parse_job_submission(body);
  } catch (const ProtocolError& e) {
    return e.what();
  }
  return "(accepted)";
}

TEST(Sequences, ASubmissionOfFramesIsSortedByNumber) {
  const std::string sha(64, 'a'), other(64, 'b');
  const JobSubmission s = parse_job_submission(
      R"({"frames": [{"number": 12, "scene": {"f": 12}},
                     {"number": 3, "scene": {"f": 3}, "assets": {"tex.exr": ")" + other + R"("}},
                     {"number": 7, "scene": {"f": 7}}],
          "assets": {"tex.exr": ")" + sha + R"("}, "frame_order": "any", "spp": 4, "name": "shot"})");
  ASSERT_EQ(s.frames.size(), 3u);
  EXPECT_EQ(s.frames[0].number, 3);
  EXPECT_EQ(s.frames[1].number, 7);
  EXPECT_EQ(s.frames[2].number, 12);
  EXPECT_EQ(s.frames[0].scene, json({{"f", 3}}));
  EXPECT_EQ(s.frames[2].scene, json({{"f", 12}}));
  EXPECT_EQ(s.frames[0].assets, (std::map<std::string, std::string>{{"tex.exr", other}}));
  EXPECT_TRUE(s.frames[1].assets.empty());  // the submission's assets apply to it
  EXPECT_EQ(s.assets, (std::map<std::string, std::string>{{"tex.exr", sha}}));
  EXPECT_EQ(s.frame_order, FrameOrder::any);
  EXPECT_EQ(s.scene, json::object());  // a sequence has no scene of its own
  EXPECT_EQ(s.sampling.spp, 4u);
  EXPECT_EQ(s.name, "shot");
  // The default order, frame numbers at both ends of their range, and one frame is a sequence too.
  EXPECT_EQ(parse_job_submission(R"({"frames": [{"number": 0, "scene": {}}]})").frame_order, FrameOrder::in_order);
  EXPECT_EQ(parse_job_submission(R"({"frames": [{"number": 999999999, "scene": {}}], "frame_order": "in_order"})")
                .frames[0].number, kMaxFrameNumber);
  // A one-image submission has no frames.
  EXPECT_TRUE(parse_job_submission(R"({"scene": {}})").frames.empty());
}

TEST(Sequences, ASubmissionOfFramesRoundTrips) {
  const std::string sha(64, 'c');
  const JobSubmission s = parse_job_submission(
      R"({"frames": [{"number": 2, "scene": {"b": 1}}, {"number": 1, "scene": {"a": 1}, "assets": {"m.obj": ")" + sha +
      R"("}}], "frame_order": "any", "tile_size": 16, "priority": 2, "seed": 9, "tile_timeout_seconds": 60})");
  const json j = json(s);
  EXPECT_FALSE(j.contains("scene"));
  EXPECT_EQ(j["frame_order"], "any");
  EXPECT_EQ(j["frames"], json::parse(R"([{"number": 1, "scene": {"a": 1}, "assets": {"m.obj": ")" + sha +
                                     R"("}}, {"number": 2, "scene": {"b": 1}}])"));
  const JobSubmission back = parse_job_submission(j.dump());
  EXPECT_EQ(json(back), j);
  EXPECT_EQ(back.tile_size, 16);
  EXPECT_EQ(back.priority, 2);
  EXPECT_EQ(back.sampling.seed, 9u);
  EXPECT_EQ(back.tile_timeout_seconds, 60);
  // In order is the default, and left out; a one-image submission writes neither key.
  JobSubmission in_order = s;
  in_order.frame_order = FrameOrder::in_order;
  EXPECT_FALSE(json(in_order).contains("frame_order"));
  EXPECT_EQ(parse_job_submission(json(in_order).dump()).frame_order, FrameOrder::in_order);
  const json image = json(parse_job_submission(R"({"scene": {"a": 1}})"));
  EXPECT_EQ(image["scene"], json({{"a", 1}}));
  EXPECT_FALSE(image.contains("frames"));
  EXPECT_FALSE(image.contains("frame_order"));
}

TEST(Sequences, ABadSubmissionOfFramesIsRefusedWithASentence) {
  const auto refused = submission_refusal;
  // Scene or frames, never both, never neither; frame_order only with frames.
  EXPECT_EQ(refused(R"({"scene": {}, "frames": [{"number": 1, "scene": {}}]})"),
            "a submission has either 'scene' (one image) or 'frames' (a sequence)");
  EXPECT_EQ(refused(R"({"name": "x"})"), "'scene' is missing (or 'frames', for a sequence)");
  EXPECT_EQ(refused(R"({"scene": {}, "frame_order": "any"})"), "'frame_order' applies only to a sequence ('frames')");
  EXPECT_EQ(refused(R"({"frame_order": "any"})"), "'scene' is missing (or 'frames', for a sequence)");
  // The list itself.
  const std::string not_a_list = "'frames' must be a non-empty array of {\"number\", \"scene\"} objects";
  EXPECT_EQ(refused(R"({"frames": []})"), not_a_list);
  EXPECT_EQ(refused(R"({"frames": {}})"), not_a_list);
  EXPECT_EQ(refused(R"({"frames": null})"), not_a_list);
  EXPECT_EQ(refused(R"({"frames": "1-10"})"), not_a_list);
  EXPECT_EQ(refused(R"({"frames": [3]})"), "'frames[0]' must be an object {\"number\", \"scene\"}");
  // Numbers: present, whole, unique, within 0..999999999 (a refusal names the frame's place in the list).
  EXPECT_EQ(refused(R"({"frames": [{"number": 1, "scene": {}}, {"number": 1, "scene": {"x": 1}}]})"),
            "frame 1 appears twice in 'frames'");
  EXPECT_EQ(refused(R"({"frames": [{"number": 5, "scene": {}}, {"number": 2, "scene": {}}, {"number": 5,
                       "scene": {}}]})"),
            "frame 5 appears twice in 'frames'");
  const std::string range = ".number' must be a frame number from 0 to 999999999";
  EXPECT_EQ(refused(R"({"frames": [{"number": 1, "scene": {}}, {"number": -1, "scene": {}}]})"), "'frames[1]" + range);
  EXPECT_EQ(refused(R"({"frames": [{"number": 1000000000, "scene": {}}]})"), "'frames[0]" + range);
  EXPECT_EQ(refused(R"({"frames": [{"number": 18446744073709551615, "scene": {}}]})"), "'frames[0]" + range);
  EXPECT_EQ(refused(R"({"frames": [{"number": 9223372036854775808, "scene": {}}]})"), "'frames[0]" + range);
  EXPECT_EQ(refused(R"({"frames": [{"number": 1.5, "scene": {}}]})"), "'frames[0]" + range);
  EXPECT_EQ(refused(R"({"frames": [{"number": "1", "scene": {}}]})"), "'frames[0]" + range);
  EXPECT_EQ(refused(R"({"frames": [{"number": true, "scene": {}}]})"), "'frames[0]" + range);
  EXPECT_EQ(refused(R"({"frames": [{"scene": {}}]})"), "'frames[0]" + range);
  // Each frame's keys: number, scene and assets only; its scene an object.
  EXPECT_EQ(refused(R"({"frames": [{"number": 1, "scene": {}, "spp": 4}]})"),
            "'frames[0]' has an unknown key 'spp' (known: number, scene, assets)");
  EXPECT_EQ(refused(R"({"frames": [{"number": 4}]})"), "'frames[0].scene' (frame 4) must be a JSON object");
  EXPECT_EQ(refused(R"({"frames": [{"number": 4, "scene": "shot.json"}]})"),
            "'frames[0].scene' (frame 4) must be a JSON object");
  // A frame's assets are checked as the submission's are, and the refusal says where.
  EXPECT_EQ(refused(R"({"frames": [{"number": 1, "scene": {}}, {"number": 2, "scene": {}, "assets": ["a.obj"]}]})"),
            "'frames[1].assets' must be an object mapping scene paths to SHA-256 hashes");
  EXPECT_EQ(refused(R"({"frames": [{"number": 1, "scene": {}, "assets": {"a.obj": "ABC"}}]})"),
            "frames[0].assets[\"a.obj\"] must be a lowercase hex SHA-256 (got \"ABC\")");
  EXPECT_EQ(refused(R"({"frames": [{"number": 1, "scene": {}, "assets": {"a.obj": ")" + std::string(64, 'A') +
                    R"("}}]})"),
            "frames[0].assets[\"a.obj\"] must be a lowercase hex SHA-256 (got \"" + std::string(64, 'A') + "\")");
  EXPECT_EQ(refused(R"({"frames": [{"number": 1, "scene": {}}], "assets": {"a.obj": 1}})"),
            "assets[\"a.obj\"] must be a lowercase hex SHA-256 (got 1)");
  // The order's name.
  EXPECT_EQ(refused(R"({"frames": [{"number": 1, "scene": {}}], "frame_order": "random"})"),
            "'frame_order' must be \"in_order\" or \"any\" (got \"random\")");
  EXPECT_EQ(refused(R"({"frames": [{"number": 1, "scene": {}}], "frame_order": ""})"),
            "'frame_order' must be \"in_order\" or \"any\" (got \"\")");
  EXPECT_EQ(refused(R"({"frames": [{"number": 1, "scene": {}}], "frame_order": 1})"),
            "'frame_order' must be a string (got 1)");
  // The shared settings are checked as for one image.
  EXPECT_EQ(refused(R"({"frames": [{"number": 1, "scene": {}}], "replicates": 99})"),
            "'replicates' must be an integer in 1..16 (got 99)");
}

TEST(Sequences, ARetryNamesFramesOrNothing) {
  EXPECT_TRUE(parse_retry_request("").frames.empty());  // the whole job (or every failed and cancelled frame)
  EXPECT_TRUE(parse_retry_request(" \n").frames.empty());
  EXPECT_TRUE(parse_retry_request("{}").frames.empty());
  EXPECT_EQ(parse_retry_request(R"({"frames": [7, 2, 999999999, 0]})").frames,
            (std::vector<int64_t>{7, 2, 999999999, 0}));  // as given: the coordinator looks each one up
  EXPECT_EQ(json(RetryRequest{{1, 2}}), json::parse(R"({"frames": [1, 2]})"));
  EXPECT_EQ(json(RetryRequest{}), json::object());
  EXPECT_EQ(parse_retry_request(json(RetryRequest{{4, 5}}).dump()).frames, (std::vector<int64_t>{4, 5}));
  EXPECT_TRUE(parse_retry_request(json(RetryRequest{}).dump()).frames.empty());
}

TEST(Sequences, ABadRetryIsRefusedWithASentence) {
  const auto refusal = [](const std::string& body) {
    try {
      parse_retry_request(body);
    } catch (const ProtocolError& e) {
      return std::string(e.what());
    }
    return std::string("(accepted)");
  };
  const std::string list = "'frames' must be a non-empty array of at most 100000 frame numbers";
  EXPECT_EQ(refusal(R"({"frames": []})"), list);
  EXPECT_EQ(refusal(R"({"frames": "1-3"})"), list);
  EXPECT_EQ(refusal(R"({"frames": 3})"), list);
  EXPECT_EQ(refusal(R"({"frames": null})"), list);
  EXPECT_EQ(refusal(json{{"frames", std::vector<int64_t>(size_t(kDefaultMaxJobFrames) + 1, 1)}}.dump()), list);
  EXPECT_EQ(refusal(json{{"frames", std::vector<int64_t>(size_t(kDefaultMaxJobFrames), 1)}}.dump()), "(accepted)");
  EXPECT_EQ(refusal(R"({"frames": [1, -1]})"), "frames[1] must be a frame number from 0 to 999999999 (got -1)");
  EXPECT_EQ(refusal(R"({"frames": [1000000000]})"),
            "frames[0] must be a frame number from 0 to 999999999 (got 1000000000)");
  EXPECT_EQ(refusal(R"({"frames": [18446744073709551615]})"),
            "frames[0] must be a frame number from 0 to 999999999 (got 18446744073709551615)");
  EXPECT_EQ(refusal(R"({"frames": [2.5]})"), "frames[0] must be a frame number from 0 to 999999999 (got 2.5)");
  EXPECT_EQ(refusal(R"({"frames": ["3"]})"), "frames[0] must be a frame number from 0 to 999999999 (got \"3\")");
  EXPECT_EQ(refusal(R"({"frames": [[3]]})"), "frames[0] must be a frame number from 0 to 999999999 (got [3])");
  EXPECT_EQ(refusal(R"({"frame": [3]})"), "unknown key 'frame' (known keys: frames)");
  EXPECT_EQ(refusal("[3]"), "expected a JSON object, got array");
  EXPECT_EQ(refusal("null"), "expected a JSON object, got null");
  EXPECT_EQ(refusal(R"({"frames": [1)").rfind("malformed JSON: ", 0), 0u);
}

TEST(Sequences, FrameOrdersHaveTheProtocolsNames) {
  EXPECT_STREQ(to_string(FrameOrder::in_order), "in_order");
  EXPECT_STREQ(to_string(FrameOrder::any), "any");
  EXPECT_EQ(frame_order_from_string("any"), FrameOrder::any);
  EXPECT_EQ(frame_order_from_string("in_order"), FrameOrder::in_order);
  EXPECT_THROW(frame_order_from_string("In_Order"), std::invalid_argument);
  EXPECT_EQ(frame_job_id("j-4", 17), "j-4.f17");
  EXPECT_EQ(frame_job_id("j-4", 0), "j-4.f0");
}

TEST(Sequences, TheFrameRoutesAreBuiltAndMatched) {
  EXPECT_EQ(routes::job_frames("j-2"), "/v1/jobs/j-2/frames");
  EXPECT_EQ(routes::job_frame_result("j-2", 7), "/v1/jobs/j-2/frames/7/result.exr");
  const RouteMatch list = match_route("/v1/jobs/j-2/frames?after=3&limit=10");
  ASSERT_NE(list.route, nullptr);
  EXPECT_EQ(list.route->endpoint, Endpoint::job_frames);
  EXPECT_EQ(list.param, "j-2");
  const RouteMatch result = match_route("/v1/jobs/j-2/frames/7/result.exr");
  ASSERT_NE(result.route, nullptr);
  EXPECT_EQ(result.route->endpoint, Endpoint::job_frame_result);
  EXPECT_EQ(result.param, "j-2");
  EXPECT_EQ(result.param2, "7");
  EXPECT_EQ(match_route("/v1/jobs/j-2/frames/7").route, nullptr);
  // A frame's own job is an ordinary job id.
  const RouteMatch frame_job = match_route("/v1/jobs/j-2.f7/result.exr");
  ASSERT_NE(frame_job.route, nullptr);
  EXPECT_EQ(frame_job.route->endpoint, Endpoint::job_result);
  EXPECT_EQ(frame_job.param, "j-2.f7");
}

TEST(Sequences, ASequencesJobCarriesItsFrameCountsAndOrder) {
  JobStatus s;
  s.id = "j-4";
  s.state = JobState::failed;
  s.params.width = 16;
  s.params.height = 8;
  s.params.frame_order = FrameOrder::any;
  s.tiles = {8, 6, 0, 2};
  s.error = "1 of 4 frames failed; frame 2: boom";
  s.frames = FrameCounts{.total = 4, .queued = 0, .running = 0, .paused = 0, .done = 3, .failed = 1, .cancelled = 0,
                         .first = 1, .last = 4};
  const json j = json(s);
  EXPECT_EQ(j["frames"], json::parse(R"({"total": 4, "queued": 0, "running": 0, "paused": 0, "done": 3, "failed": 1,
                                         "cancelled": 0, "waiting": 0, "blocked": 0, "first": 1, "last": 4})"));
  EXPECT_EQ(j["frame_order"], "any");
  EXPECT_EQ(j["scene_hash"], "");
  EXPECT_FALSE(j.contains("sequence"));
  EXPECT_FALSE(j.contains("frame"));
  const JobStatus back = parse_answer<JobStatus>(j.dump(), "job");
  ASSERT_TRUE(back.frames);
  EXPECT_EQ(back.frames->total, 4);
  EXPECT_EQ(back.frames->done, 3);
  EXPECT_EQ(back.frames->failed, 1);
  EXPECT_EQ(back.frames->first, 1);
  EXPECT_EQ(back.frames->last, 4);
  EXPECT_EQ(back.params.frame_order, FrameOrder::any);
  EXPECT_FALSE(back.sequence);
  EXPECT_FALSE(back.frame);
  EXPECT_EQ(json(back), j);
  // Missing counts are 0, a missing total is refused, and so is an order with another name.
  const JobStatus sparse = parse_answer<JobStatus>(
      R"({"id": "j-4", "state": "queued", "frames": {"total": 2, "queued": 2}, "frame_order": "in_order"})", "job");
  EXPECT_EQ(sparse.frames->queued, 2);
  EXPECT_EQ(sparse.frames->done, 0);
  EXPECT_EQ(sparse.frames->last, 0);
  EXPECT_THROW(parse_answer<JobStatus>(R"({"id": "j-4", "state": "queued", "frames": {"queued": 2}})", "job"),
               ProtocolError);
  EXPECT_THROW(parse_answer<JobStatus>(R"({"id": "j-4", "state": "queued", "frames": {"total": "2"}})", "job"),
               ProtocolError);
  EXPECT_THROW(parse_answer<JobStatus>(R"({"id": "j-4", "state": "queued", "frame_order": "sideways"})", "job"),
               ProtocolError);
}

TEST(Sequences, AFramesJobNamesItsSequenceAndNumber) {
  JobStatus f;
  f.id = frame_job_id("j-4", 2);
  f.state = JobState::done;
  f.params.scene_hash = "h2";
  f.sequence = "j-4";
  f.frame = 2;
  const json j = json(f);
  EXPECT_EQ(j["sequence"], "j-4");
  EXPECT_EQ(j["frame"], 2);
  EXPECT_FALSE(j.contains("frames"));  // a frame's job has no frames, and no order of its own
  EXPECT_FALSE(j.contains("frame_order"));
  const JobStatus back = parse_answer<JobStatus>(j.dump(), "job");
  EXPECT_EQ(back.id, "j-4.f2");
  EXPECT_EQ(back.sequence, "j-4");
  EXPECT_EQ(back.frame, 2);
  EXPECT_FALSE(back.frames);
  EXPECT_EQ(json(back), j);
  // A one-image job writes none of the sequence keys, and null ones read as absent.
  const json image = json(JobStatus{});
  for (const char* key : {"frames", "frame_order", "sequence", "frame"}) EXPECT_FALSE(image.contains(key)) << key;
  const JobStatus nulls =
      parse_answer<JobStatus>(R"({"id": "j-1", "state": "queued", "sequence": null, "frame": null})", "job");
  EXPECT_FALSE(nulls.sequence);
  EXPECT_FALSE(nulls.frame);
  EXPECT_THROW(parse_answer<JobStatus>(R"({"id": "j-1", "state": "queued", "frame": "2"})", "job"), ProtocolError);
}

TEST(Sequences, AFrameListPagesFramesJobs) {
  JobStatus f1, f3;
  f1.id = "j-4.f1";
  f1.sequence = "j-4";
  f1.frame = 1;
  f1.state = JobState::done;
  f3 = f1;
  f3.id = "j-4.f3";
  f3.frame = 3;
  f3.state = JobState::running;
  const json page = json(FrameList{{f1, f3}, 3});
  EXPECT_EQ(page["next"], 3);
  ASSERT_EQ(page["frames"].size(), 2u);
  EXPECT_EQ(page["frames"][1]["frame"], 3);
  const FrameList back = parse_answer<FrameList>(page.dump(), "frame list");
  ASSERT_EQ(back.frames.size(), 2u);
  EXPECT_EQ(back.frames[0].id, "j-4.f1");
  EXPECT_EQ(back.frames[1].frame, 3);
  EXPECT_EQ(back.frames[1].state, JobState::running);
  EXPECT_EQ(back.next, 3);
  EXPECT_EQ(json(back), page);
  // The last page: next is null, and is written so.
  const json last = json(FrameList{{f3}, std::nullopt});
  EXPECT_TRUE(last.contains("next"));
  EXPECT_TRUE(last["next"].is_null());
  EXPECT_FALSE(parse_answer<FrameList>(last.dump(), "frame list").next);
  EXPECT_EQ(json(FrameList{}), json::parse(R"({"frames": [], "next": null})"));
  EXPECT_THROW(parse_answer<FrameList>(R"({"next": 2})", "frame list"), ProtocolError);
  EXPECT_THROW(parse_answer<FrameList>(R"({"frames": [], "next": "c2"})", "frame list"), ProtocolError);
}

TEST(Sequences, AFrameEventNamesTheSequenceTheFrameAndItsJob) {
  const json j = json(FrameEvent{"j-4", 17, "j-4.f17"});
  EXPECT_EQ(j, json::parse(R"({"job": "j-4", "frame": 17, "frame_job": "j-4.f17"})"));
  const FrameEvent back = j.get<FrameEvent>();
  EXPECT_EQ(back.job, "j-4");
  EXPECT_EQ(back.frame, 17);
  EXPECT_EQ(back.frame_job, "j-4.f17");
  EXPECT_THROW((void)json::parse(R"({"job": "j-4", "frame": 17})").get<FrameEvent>(), ProtocolError);
  EXPECT_THROW((void)json::parse(R"({"job": "j-4", "frame": "17", "frame_job": "j-4.f17"})").get<FrameEvent>(),
               ProtocolError);
  EXPECT_STREQ(events::kFrameDone, "frame_done");
  EXPECT_NE(std::find(std::begin(events::kFilterable), std::end(events::kFilterable), std::string_view("frame_done")),
            std::end(events::kFilterable));
}

}  // namespace
}  // namespace tessera::protocol
