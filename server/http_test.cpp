// The coordinator over real HTTP on a loopback ephemeral port, driven by a small synchronous Beast client.
#include "server/coordinator.h"
#include "server/database.h"
#include "server/test_coordinator.h"
#include "server/test_http_client.h"
#include "server/test_sse_client.h"

#include "core/render/render.h"
#include "core/scene/scene_loader.h"
#include "core/util/sha256.h"
#include "core/image/tiles.h"

#include <boost/asio/connect.hpp>
#include <boost/asio/ip/tcp.hpp>
#include <boost/beast/core.hpp>
#include <boost/beast/http.hpp>
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>
#include <spdlog/spdlog.h>

#include <arpa/inet.h>
#include <fcntl.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <future>
#include <map>
#include <mutex>
#include <sstream>
#include <thread>

namespace tessera::server {
namespace {

namespace asio = boost::asio;
namespace beast = boost::beast;
namespace fs = std::filesystem;
using nlohmann::json;
using tcp = asio::ip::tcp;

const fs::path kCourse = TESSERA_COURSE_DIR;

std::string slurp(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  std::ostringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

using testing::Client;
using testing::Reply;

// A coordinator on 127.0.0.1:0 with a fresh data folder, served on a background thread.
class HttpTest : public ::testing::Test {
 protected:
  void SetUp() override {
    spdlog::set_level(spdlog::level::warn);
    CoordinatorOptions o;
    o.limits.json_limit = 256 * 1024;
    o.limits.blob_limit = 1 << 20;
    o.limits.result_limit = 4 << 20;
    o.handler_threads = 2;
    o.lease_seconds = lease_seconds_;
    configure(o);
    server_ = std::make_unique<testing::RunningCoordinator>(o, "http");
  }
  void TearDown() override { server_.reset(); }
  // A request that acts as a worker (its lease requests; its leases' heartbeats, uploads, failure reports, releases
  // and states) carries that worker's secret, as `tessera worker` sends it, unless it names a secret of its own.
  Reply call(http::verb m, const std::string& target, std::string body = {},
             std::vector<std::pair<std::string, std::string>> headers = {}) {
    const protocol::RouteMatch route = protocol::match_route(target);
    const bool own_secret = std::any_of(headers.begin(), headers.end(),
                                        [](const auto& h) { return h.first == protocol::kWorkerSecretHeader; });
    if (!own_secret)
      if (const std::string secret = secret_for(route); !secret.empty())
        headers.emplace_back(protocol::kWorkerSecretHeader, secret);
    Client c(server_->endpoint());
    Reply r = c.send(m, target, std::move(body), std::move(headers));
    std::lock_guard lock(identities_mu_);
    if (route.endpoint() == protocol::Endpoint::workers && r.status == 201)
      secrets_[r.js().value("id", "")] = r.js().value("secret", "");
    if (route.endpoint() == protocol::Endpoint::worker_lease && r.status == 200)
      lease_workers_[r.js().value("lease", "")] = route.param;
    if (route.endpoint() == protocol::Endpoint::lease_result && r.status == 200 && r.js().contains("next"))
      lease_workers_[r.js()["next"].value("lease", "")] = lease_workers_[route.param];  // the next lease it asked for
    return r;
  }
  // The secret of the worker a request to `route` acts as ("" for none known).
  std::string secret_for(const protocol::RouteMatch& route) {
    std::lock_guard lock(identities_mu_);
    std::string worker;
    switch (route.endpoint()) {
      case protocol::Endpoint::worker_lease: worker = route.param; break;
      case protocol::Endpoint::lease_heartbeat:
      case protocol::Endpoint::lease_result:
      case protocol::Endpoint::lease_fail:
      case protocol::Endpoint::lease_release:
      case protocol::Endpoint::lease_state:
        if (const auto l = lease_workers_.find(route.param); l != lease_workers_.end()) worker = l->second;
        break;
      default: return {};
    }
    const auto it = secrets_.find(worker);
    return it == secrets_.end() ? std::string() : it->second;
  }
  std::string put_blob(const fs::path& file) {
    const std::string bytes = slurp(file);
    const std::string h = sha256_hex(bytes);
    const Reply r = call(http::verb::put, "/v1/blobs/" + h, bytes);
    EXPECT_TRUE(r.status == 201 || r.status == 200) << r.body;
    return h;
  }
  // Uploads every asset of a sample scene and returns the job body for it.
  json job_for(const std::string& scene_file) {
    const json scene = json::parse(slurp(kCourse / scene_file));
    json assets = json::object();
    for (const std::string& p : scene_asset_paths(scene)) assets[p] = put_blob(kCourse / p);
    return {{"scene", scene}, {"assets", assets}};
  }
  std::string submit(const json& body) {
    const Reply r = call(http::verb::post, "/v1/jobs", body.dump(), {{"Content-Type", "application/json"}});
    EXPECT_EQ(r.status, 201u) << r.body;
    return r.js().value("id", "");
  }
  std::string register_worker(const std::string& name = "test") {
    const Reply r = call(http::verb::post, "/v1/workers", json{{"name", name}, {"threads", 1}, {"version", "0"}}.dump());
    EXPECT_EQ(r.status, 201u) << r.body;
    return r.js().value("id", "");
  }

  /// Two workers render a small job tile by tile (an invalid and a duplicate upload among them); the merged result is
  /// bitwise one render's.
  void check_full_round_trip();

  /// Lets a derived fixture change the options (limits) before the coordinator starts.
  virtual void configure(CoordinatorOptions&) {}

  double lease_seconds_ = 30;
  std::unique_ptr<testing::RunningCoordinator> server_;
  std::mutex identities_mu_;
  std::map<std::string, std::string> secrets_;        // worker id -> its secret (identities_mu_)
  std::map<std::string, std::string> lease_workers_;  // lease id -> the worker it was granted to (identities_mu_)
};

// A small job on the intersection_test Cornell box: 40x30 pixels, 2 spp, 16-pixel tiles (3x2 tiles, ragged edges).
json small_cbox(json job) {
  job["scene"]["film"]["resolution"] = {40, 30};
  job["spp"] = 2;
  job["seed"] = 7;
  job["tile_size"] = 16;
  return job;
}

// The Cornell box loaded straight from the sample folder, as the CLI would.
LoadedScene load_local(const json& scene, uint32_t spp) {
  LoadOptions lo;
  lo.spp = spp;
  return load_scene_json(scene, "scene", [](const std::string& rel, const std::string&) { return kCourse / rel; }, lo);
}

std::string tile_exr(const fs::path& dir, const Image& img, const PixelWindow& window, int w, int h) {
  const fs::path p = dir / ("tile-" + random_hex(4) + ".exr");
  ExrWriteOptions o;
  o.data_window = window;
  o.display_window = PixelWindow{0, 0, w, h};
  write_exr(p, img, o);
  std::string bytes = slurp(p);
  fs::remove(p);
  return bytes;
}

TEST_F(HttpTest, HealthAndMetrics) {
  Reply r = call(http::verb::get, "/healthz");
  EXPECT_EQ(r.status, 200u);
  EXPECT_EQ(r.js()["status"], "ok");
  r = call(http::verb::get, "/metrics");
  EXPECT_EQ(r.status, 200u);
  EXPECT_NE(r.body.find("tessera_jobs{state=\"queued\"} 0"), std::string::npos) << r.body;
  EXPECT_NE(r.body.find("tessera_http_request_duration_seconds_count{route=\"GET /healthz\"} 1"), std::string::npos) << r.body;
  EXPECT_EQ(r.msg[http::field::content_type], "text/plain; version=0.0.4");

  // A submission is a commit, acknowledged after a flush: the store's disk costs count it.
  const auto metric = [&](const std::string& name) {
    const size_t at = r.body.find("\n" + name + " ");
    return at == std::string::npos ? -1.0 : std::stod(r.body.substr(at + name.size() + 2));
  };
  submit(small_cbox(job_for("cbox_no_light.json")));
  r = call(http::verb::get, "/metrics");
  EXPECT_GE(metric("tessera_store_flush_duration_seconds_count"), 1.0) << r.body;
  EXPECT_GT(metric("tessera_store_log_pages_total"), 0.0) << r.body;
  EXPECT_NE(r.body.find("tessera_store_flush_duration_seconds_bucket{le=\"+Inf\"}"), std::string::npos) << r.body;
}

TEST_F(HttpTest, BlobUploadGoodBadAndRepeat) {
  const std::string bytes = "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n";
  const std::string h = sha256_hex(bytes);
  EXPECT_EQ(call(http::verb::head, "/v1/blobs/" + h).status, 404u);
  Reply r = call(http::verb::put, "/v1/blobs/" + h, bytes);
  EXPECT_EQ(r.status, 201u) << r.body;
  EXPECT_EQ(r.js()["sha256"], h);
  EXPECT_EQ(r.js()["size"], bytes.size());
  r = call(http::verb::put, "/v1/blobs/" + h, bytes);
  EXPECT_EQ(r.status, 200u) << r.body;
  EXPECT_EQ(call(http::verb::head, "/v1/blobs/" + h).status, 200u);
  r = call(http::verb::get, "/v1/blobs/" + h);
  EXPECT_EQ(r.status, 200u);
  EXPECT_EQ(r.body, bytes);
  // Wrong hash: refused, names both hashes, nothing stored.
  const std::string other = sha256_hex("something else");
  r = call(http::verb::put, "/v1/blobs/" + other, bytes);
  EXPECT_EQ(r.status, 400u);
  EXPECT_EQ(r.js()["error"], "body hashes to " + h + ", not " + other);
  EXPECT_EQ(call(http::verb::get, "/v1/blobs/" + other).status, 404u);
  r = call(http::verb::put, "/v1/blobs/NOTAHASH", bytes);
  EXPECT_EQ(r.status, 400u);
  EXPECT_NE(r.js()["error"].get<std::string>().find("64"), std::string::npos);
  // Above the blob limit (1 MiB in this fixture).
  const std::string big(size_t(1) << 21, 'x');
  r = call(http::verb::put, "/v1/blobs/" + sha256_hex(big), big);
  EXPECT_EQ(r.status, 413u);
}

TEST_F(HttpTest, OneQueryTellsWhichBlobsAreMissing) {
  const std::string stored = "a stored asset", absent = "an asset never uploaded";
  ASSERT_EQ(call(http::verb::put, "/v1/blobs/" + sha256_hex(stored), stored).status, 201u);
  // Stored an hour ago, as far as the collector's grace period goes: the query starts it again, as HEAD does.
  fs::path file;
  for (const auto& e : fs::recursive_directory_iterator(server_->data_dir()))
    if (e.path().filename() == sha256_hex(stored)) file = e.path();
  ASSERT_FALSE(file.empty());
  fs::last_write_time(file, fs::file_time_type::clock::now() - std::chrono::hours(1));
  Reply r = call(http::verb::post, "/v1/blobs",
                 json{{"sha256", {sha256_hex(absent), sha256_hex(stored), sha256_hex(absent)}}}.dump());
  ASSERT_EQ(r.status, 200u) << r.body;
  EXPECT_EQ(r.js()["missing"], json::array({sha256_hex(absent), sha256_hex(absent)}));  // in the query's order
  EXPECT_GT(fs::last_write_time(file), fs::file_time_type::clock::now() - std::chrono::minutes(1));
  r = call(http::verb::post, "/v1/blobs", R"({"sha256": []})");
  ASSERT_EQ(r.status, 200u) << r.body;
  EXPECT_EQ(r.js()["missing"], json::array());
  r = call(http::verb::post, "/v1/blobs", R"({"sha256": ["not a hash"]})");
  EXPECT_EQ(r.status, 400u);
  EXPECT_NE(r.js()["error"].get<std::string>().find("\"sha256\"[0]"), std::string::npos) << r.body;
  EXPECT_EQ(call(http::verb::post, "/v1/blobs", "").status, 400u);
  EXPECT_EQ(call(http::verb::get, "/v1/blobs").status, 405u);
}

TEST_F(HttpTest, SubmitValidJobAndListIt) {
  const json body = small_cbox(job_for("cbox_no_light.json"));
  const Reply r = call(http::verb::post, "/v1/jobs", body.dump());
  ASSERT_EQ(r.status, 201u) << r.body;
  const std::string id = r.js()["id"];
  EXPECT_EQ(r.msg[http::field::location], "/v1/jobs/" + id);
  const Reply g = call(http::verb::get, "/v1/jobs/" + id);
  ASSERT_EQ(g.status, 200u);
  const json j = g.js();
  EXPECT_EQ(j["state"], "queued");
  EXPECT_EQ(j["width"], 40);
  EXPECT_EQ(j["height"], 30);
  EXPECT_EQ(j["spp"], 2);
  EXPECT_EQ(j["tiles"]["total"], 6);
  EXPECT_EQ(j["tiles"]["pending"], 6);
  EXPECT_TRUE(j["finished_ms"].is_null());
  EXPECT_EQ(j["scene_hash"].get<std::string>().size(), 64u);
  const Reply list = call(http::verb::get, "/v1/jobs");
  ASSERT_EQ(list.status, 200u);
  ASSERT_EQ(list.js()["jobs"].size(), 1u);
  EXPECT_EQ(list.js()["jobs"][0]["id"], id);
  const Reply spec = call(http::verb::get, "/v1/jobs/" + id + "/spec");
  ASSERT_EQ(spec.status, 200u);
  EXPECT_EQ(spec.js()["scene"], body["scene"]);
  EXPECT_EQ(spec.js()["assets"], body["assets"]);
  EXPECT_EQ(spec.js()["width"], 40);
  EXPECT_EQ(spec.js()["seed"], 7);
  EXPECT_EQ(call(http::verb::get, "/v1/jobs/" + id + "/result.exr").status, 409u);
  EXPECT_EQ(call(http::verb::get, "/v1/jobs/" + id + "/preview.png").status, 200u);
}

TEST_F(HttpTest, SubmitWithMissingAssetsNamesThem) {
  json body = job_for("cbox_no_light.json");
  const std::string first = body["assets"].begin().key();
  body["assets"].erase(first);
  const std::string second = body["assets"].begin().key();
  body["assets"][second] = sha256_hex("never uploaded");
  const Reply r = call(http::verb::post, "/v1/jobs", body.dump());
  ASSERT_EQ(r.status, 400u) << r.body;
  const std::string e = r.js()["error"];
  EXPECT_EQ(e.rfind("missing assets: ", 0), 0u) << e;
  EXPECT_NE(e.find(first + " (not in \"assets\")"), std::string::npos) << e;
  EXPECT_NE(e.find(second + " (not uploaded)"), std::string::npos) << e;
}

TEST_F(HttpTest, SceneErrorsCarryTheLoaderMessageWithTheJsonPath) {
  json scene = {{"integrator", {{"type", "intersection_test"}}},
                {"film", {{"resolution", {8, 8}}}},
                {"textures", {{"t", {{"type", "constant"}, {"color", {1, 1, 1}}}}}},
                {"materials", {{"m", {{"type", "diffuse"}, {"texture_name", "t"}}}}},
                {"objects", json::array({{{"type", "sphere"}, {"radius", 1}, {"material_name", "m"}},
                                         {{"type", "sphere"}, {"radius", -1}, {"material_name", "m"}}})}};
  Reply r = call(http::verb::post, "/v1/jobs", json{{"scene", scene}}.dump());
  ASSERT_EQ(r.status, 400u) << r.body;
  EXPECT_EQ(r.js()["error"].get<std::string>().rfind("scene: objects[1].radius: must not be negative", 0), 0u) << r.body;
  // A scene the loader accepts works without assets.
  scene["objects"].erase(1);
  r = call(http::verb::post, "/v1/jobs", json{{"scene", scene}}.dump());
  EXPECT_EQ(r.status, 201u) << r.body;
  // The bdpt box renders with the path tracer; an unsupported integrator type needs integrator "direct", as
  // `tessera render --integrator direct`.
  json bdpt = job_for("cbox.json");
  EXPECT_EQ(call(http::verb::post, "/v1/jobs", bdpt.dump()).status, 201u);
  bdpt["scene"]["integrator"]["type"] = "photon";
  r = call(http::verb::post, "/v1/jobs", bdpt.dump());
  ASSERT_EQ(r.status, 400u) << r.body;
  EXPECT_NE(r.js()["error"].get<std::string>().find("integrator.type"), std::string::npos) << r.body;
  bdpt["integrator"] = "direct";
  EXPECT_EQ(call(http::verb::post, "/v1/jobs", bdpt.dump()).status, 201u);
}

TEST_F(HttpTest, MalformedUnknownKeysAndOversizedBodies) {
  Reply r = call(http::verb::post, "/v1/jobs", "{\"scene\": ");
  ASSERT_EQ(r.status, 400u);
  EXPECT_EQ(r.js()["error"].get<std::string>().rfind("malformed JSON", 0), 0u) << r.body;
  r = call(http::verb::post, "/v1/jobs", "[1, 2]");
  EXPECT_EQ(r.status, 400u);
  json body = small_cbox(job_for("cbox_no_light.json"));
  body["spps"] = 4;
  r = call(http::verb::post, "/v1/jobs", body.dump());
  ASSERT_EQ(r.status, 400u);
  EXPECT_EQ(r.js()["error"].get<std::string>().rfind("unknown key 'spps'", 0), 0u) << r.body;
  body.erase("spps");
  body["tile_size"] = 0;
  r = call(http::verb::post, "/v1/jobs", body.dump());
  ASSERT_EQ(r.status, 400u);
  EXPECT_NE(r.js()["error"].get<std::string>().find("tile_size"), std::string::npos) << r.body;
  r = call(http::verb::post, "/v1/workers", R"({"name": "a", "thread": 2})");
  EXPECT_EQ(r.status, 400u);
  // Above the JSON limit (256 KiB in this fixture).
  body["name"] = std::string(300 * 1024, 'n');
  r = call(http::verb::post, "/v1/jobs", body.dump());
  EXPECT_EQ(r.status, 413u) << r.body;
  EXPECT_TRUE(r.js().contains("error"));
}

// Adaptive sampling is a job option: valid settings reach the spec workers read; invalid ones are 400 naming the key.
TEST_F(HttpTest, TargetErrorIsAJobOptionCheckedAndPassedToWorkers) {
  json body = small_cbox(job_for("cbox_no_light.json"));
  const std::pair<json, const char*> bad[] = {
      {json{{"target_error", 0}}, "target_error"},          {json{{"target_error", -1}}, "target_error"},
      {json{{"target_error", "0.1"}}, "target_error"},      {json{{"min_spp", 4}}, "only with 'target_error'"},
      {json{{"target_error", 0.1}, {"min_spp", 64}, {"max_spp", 8}}, "larger than 'max_spp'"},
      {json{{"target_error", 0.1}, {"max_spp", 0}}, "max_spp"}};
  for (const auto& [extra, says] : bad) {
    json b = body;
    b.update(extra);
    const Reply r = call(http::verb::post, "/v1/jobs", b.dump());
    ASSERT_EQ(r.status, 400u) << extra.dump();
    EXPECT_NE(r.js()["error"].get<std::string>().find(says), std::string::npos) << r.body;
  }
  body.update(json{{"target_error", 0.05}, {"min_spp", 4}, {"max_spp", 32}});
  const Reply r = call(http::verb::post, "/v1/jobs", body.dump());
  ASSERT_EQ(r.status, 201u) << r.body;
  const Reply spec = call(http::verb::get, "/v1/jobs/" + r.js()["id"].get<std::string>() + "/spec", "");
  ASSERT_EQ(spec.status, 200u);
  EXPECT_EQ(spec.js()["target_error"].get<double>(), 0.05);
  EXPECT_EQ(spec.js()["min_spp"].get<int>(), 4);
  EXPECT_EQ(spec.js()["max_spp"].get<int>(), 32);
}

TEST_F(HttpTest, UnknownTargetsAndWrongMethods) {
  Reply r = call(http::verb::get, "/v1/jobs/j-nope");
  EXPECT_EQ(r.status, 404u);
  EXPECT_TRUE(r.js().contains("error"));
  EXPECT_EQ(call(http::verb::get, "/v1/jobs/j-nope/result.exr").status, 404u);
  EXPECT_EQ(call(http::verb::get, "/v1/jobs/j-nope/preview.png").status, 404u);
  EXPECT_EQ(call(http::verb::get, "/v1/jobs/j-nope/spec").status, 404u);
  EXPECT_EQ(call(http::verb::delete_, "/v1/jobs/j-nope").status, 404u);
  EXPECT_EQ(call(http::verb::get, "/v2/jobs").status, 404u);
  EXPECT_EQ(call(http::verb::get, "/v1/jobs/").status, 404u);
  EXPECT_EQ(call(http::verb::post, "/v1/leases/l-nope/heartbeat").status, 404u);
  EXPECT_EQ(call(http::verb::put, "/v1/leases/l-nope/result", "x").status, 404u);
  EXPECT_EQ(call(http::verb::post, "/v1/leases/l-nope/fail", R"({"error":"x"})").status, 404u);
  EXPECT_EQ(call(http::verb::post, "/v1/leases/l-nope/release").status, 404u);
  r = call(http::verb::delete_, "/v1/blobs/" + sha256_hex("x"));
  EXPECT_EQ(r.status, 405u);
  EXPECT_EQ(r.msg[http::field::allow], "PUT, HEAD, GET");
  EXPECT_TRUE(r.js().contains("error"));
  r = call(http::verb::delete_, "/v1/workers");
  EXPECT_EQ(r.status, 405u);
  EXPECT_EQ(r.msg[http::field::allow], "GET, POST");
  r = call(http::verb::put, "/v1/jobs");
  EXPECT_EQ(r.status, 405u);
  EXPECT_EQ(r.msg[http::field::allow], "GET, POST");
}

TEST_F(HttpTest, KeepAliveServesSeveralRequestsOnOneConnection) {
  Client c(server_->endpoint());
  for (int i = 0; i < 3; ++i) {
    const Reply r = c.send(http::verb::get, "/healthz");
    EXPECT_EQ(r.status, 200u);
    EXPECT_TRUE(r.msg.keep_alive());
  }
  EXPECT_EQ(c.send(http::verb::get, "/nope").status, 404u);
  EXPECT_EQ(c.send(http::verb::get, "/healthz").status, 200u);
}

// A TCP socket listening on a free port of `host`, as a parent process would pass one to `tessera serve --listen fd:N`.
int listening_socket(const char* host) {
  const int fd = ::socket(AF_INET, SOCK_STREAM | SOCK_CLOEXEC, 0);
  sockaddr_in addr{};
  addr.sin_family = AF_INET;
  ::inet_pton(AF_INET, host, &addr.sin_addr);
  EXPECT_EQ(::bind(fd, reinterpret_cast<sockaddr*>(&addr), sizeof addr), 0) << std::strerror(errno);
  EXPECT_EQ(::listen(fd, 16), 0) << std::strerror(errno);
  return fd;
}

TEST(ListenAddress, IsHostAndPortOrAnInheritedDescriptor) {
  const auto set = [](const std::string& text) {
    CoordinatorOptions o;
    set_listen_address(o, text);
    return o;
  };
  CoordinatorOptions o = set("0.0.0.0:9000");
  EXPECT_EQ(o.host, "0.0.0.0");
  EXPECT_EQ(o.port, 9000);
  EXPECT_EQ(o.listen_fd, -1);
  EXPECT_EQ(set(":8470").host, "127.0.0.1");
  EXPECT_EQ(set("[::1]:0").host, "::1");
  EXPECT_EQ(set("8471").port, 8471);
  o = set("fd:3");
  EXPECT_EQ(o.listen_fd, 3);
  for (const char* bad : {"fd:", "fd:x", "fd:-1", "fd:3x", "fd: 3", "host:99999", "host:", "host:+80", "abc"}) {
    try {
      set(bad);
      ADD_FAILURE() << bad << " was taken";
    } catch (const std::invalid_argument& e) {
      EXPECT_NE(std::string(e.what()).find(std::string("listen address '") + bad + "' is not"), std::string::npos)
          << e.what();
    }
  }
}

TEST(HttpListenFd, AConnectionMadeBeforeTheCoordinatorStartedIsServedOnTheInheritedSocket) {
  spdlog::set_level(spdlog::level::warn);
  const int fd = listening_socket("127.0.0.1");
  sockaddr_in addr{};
  socklen_t len = sizeof addr;
  ASSERT_EQ(::getsockname(fd, reinterpret_cast<sockaddr*>(&addr), &len), 0);
  const tcp::endpoint ep(asio::ip::make_address("127.0.0.1"), ntohs(addr.sin_port));
  // Connected and the request sent while nothing accepts yet: the kernel queues both.
  asio::io_context ioc;
  tcp::socket early(ioc);
  early.connect(ep);
  beast::http::request<beast::http::string_body> req{beast::http::verb::get, "/healthz", 11};
  req.set(beast::http::field::host, "127.0.0.1");
  beast::http::write(early, req);

  CoordinatorOptions o;
  o.listen_fd = fd;
  o.handler_threads = 2;
  testing::RunningCoordinator coordinator(o, "listen-fd");
  EXPECT_EQ(coordinator.endpoint(), ep);
  beast::flat_buffer buf;
  beast::http::response<beast::http::string_body> res;
  beast::http::read(early, buf, res);
  EXPECT_EQ(res.result_int(), 200u);
  EXPECT_EQ(Client(ep).send(beast::http::verb::get, "/healthz").status, 200u);
  early.close();
}

TEST(HttpListenFd, RefusesWhatIsNotAListeningSocketAndAnOpenAddressWithoutTokens) {
  spdlog::set_level(spdlog::level::off);
  const auto refusal = [](int fd) {  // the address, or why the socket cannot be served on
    try {
      return listening_address(fd);
    } catch (const std::runtime_error& e) {
      return std::string(e.what());
    }
  };
  const int unbound = ::socket(AF_INET, SOCK_STREAM | SOCK_CLOEXEC, 0);
  EXPECT_EQ(refusal(unbound), "socket " + std::to_string(unbound) + " is not listening");
  const int udp = ::socket(AF_INET, SOCK_DGRAM | SOCK_CLOEXEC, 0);
  EXPECT_EQ(refusal(udp), "socket " + std::to_string(udp) + " is not a TCP socket");
  int pipe_fds[2];
  ASSERT_EQ(::pipe2(pipe_fds, O_CLOEXEC), 0);
  EXPECT_NE(refusal(pipe_fds[0]).find("is not an open socket"), std::string::npos) << refusal(pipe_fds[0]);
  for (int fd : {unbound, udp, pipe_fds[0], pipe_fds[1]}) ::close(fd);

  // Bound beyond loopback: the same rule as --listen, both tokens or nothing.
  const int open = listening_socket("0.0.0.0");
  EXPECT_EQ(refusal(open), "0.0.0.0");
  CoordinatorOptions o;
  o.listen_fd = open;
  o.data_dir = fs::temp_directory_path() / ("tessera-listen-fd-test-" + random_hex(6));
  try {
    Coordinator c(o);
    FAIL() << "served 0.0.0.0 without tokens";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("refusing to listen on 0.0.0.0 without access tokens"), std::string::npos)
        << e.what();
  }
  ::close(open);
  EXPECT_FALSE(fs::exists(o.data_dir));
}

TEST_F(HttpTest, AHeldLeaseRequestIsWokenByAJobSubmittedWhileItWaits) {
  const std::string w = register_worker();
  const json job = small_cbox(job_for("cbox_no_light.json"));  // its blobs uploaded before the request waits
  const auto held_request = [&](const std::string& worker) {
    return std::async(std::launch::async, [this, worker] {
      const auto t0 = std::chrono::steady_clock::now();
      Reply r = call(http::verb::post, "/v1/workers/" + worker + "/lease", R"({"wait_ms": 10000})");
      return std::make_pair(std::move(r), std::chrono::steady_clock::now() - t0);
    });
  };
  const auto wait_until_held = [&](int n) {
    const std::string line = "tessera_lease_requests_held " + std::to_string(n) + "\n";
    while (call(http::verb::get, "/metrics").body.find(line) == std::string::npos) std::this_thread::yield();
  };
  // With nothing to lease and a wait asked for, the request is held rather than answered at once...
  auto held = held_request(w);
  wait_until_held(1);
  // ...and a job submitted meanwhile wakes it: a 204 long before its 10 s are up (on any machine this suite runs on),
  // granting nothing, so that the lease goes to the worker's next request, which proves it is still there.
  const std::string id = submit(job);
  auto [woken, took] = held.get();
  EXPECT_EQ(woken.status, 204u) << woken.body;
  EXPECT_LT(took, std::chrono::milliseconds(10000));
  EXPECT_FALSE(woken.msg["X-Tessera-Held-Ms"].empty());  // and its time is counted apart from the route's
  EXPECT_NE(call(http::verb::get, "/metrics").body.find(R"x(route="POST /v1/workers/{wid}/lease (held)")x"), std::string::npos);
  wait_until_held(0);
  Reply r = call(http::verb::post, "/v1/workers/" + w + "/lease", R"({"wait_ms": 10000})");
  ASSERT_EQ(r.status, 200u) << r.body;
  EXPECT_EQ(r.js()["job"], id);
  EXPECT_EQ(r.js()["tile"], 0);  // the held request took no tile
  // A wait with nothing to lease ends in 204 when it is over, never before.
  const std::string other = register_worker("other");
  ASSERT_EQ(call(http::verb::post, "/v1/jobs/" + id + "/pause").status, 200u);
  const auto t0 = std::chrono::steady_clock::now();
  EXPECT_EQ(call(http::verb::post, "/v1/workers/" + other + "/lease", R"({"wait_ms": 50})").status, 204u);
  EXPECT_GE(std::chrono::steady_clock::now() - t0, std::chrono::milliseconds(50));
  // Resuming the job is work too.
  held = held_request(other);
  wait_until_held(1);
  ASSERT_EQ(call(http::verb::post, "/v1/jobs/" + id + "/resume").status, 200u);
  auto [resumed, after] = held.get();
  EXPECT_EQ(resumed.status, 204u);
  EXPECT_LT(after, std::chrono::milliseconds(10000));
  r = call(http::verb::post, "/v1/workers/" + other + "/lease");
  ASSERT_EQ(r.status, 200u) << r.body;
  EXPECT_EQ(r.js()["tile"], 1);
}

TEST_F(HttpTest, AStoppingCoordinatorAnswersItsHeldLeaseRequestsAtOnce) {
  const std::string w = register_worker();
  const auto t0 = std::chrono::steady_clock::now();
  std::future<Reply> held = std::async(std::launch::async, [&] {
    return call(http::verb::post, "/v1/workers/" + w + "/lease", R"({"wait_ms": 10000})");
  });
  while (call(http::verb::get, "/metrics").body.find("tessera_lease_requests_held 1\n") == std::string::npos)
    std::this_thread::yield();
  server_.reset();  // stops the coordinator: the held request is answered rather than waited out
  EXPECT_EQ(held.get().status, 204u);
  EXPECT_LT(std::chrono::steady_clock::now() - t0, std::chrono::milliseconds(10000));  // the wait was not served out
}

// A worker acts on its own leases only: with another worker's secret, a made-up one or none, every request on a
// lease (and a lease request in the worker's name) is 403, and nothing changes.
TEST_F(HttpTest, OnlyTheWorkerHoldingALeaseCanActOnIt) {
  const std::string a = register_worker("a"), b = register_worker("b");
  const std::string a_secret = secret_for(protocol::match_route(protocol::routes::worker_lease(a)));
  const std::string b_secret = secret_for(protocol::match_route(protocol::routes::worker_lease(b)));
  ASSERT_FALSE(a_secret.empty());
  ASSERT_NE(a_secret, b_secret);
  const std::string id = submit(small_cbox(job_for("cbox_no_light.json")));
  Reply r = call(http::verb::post, "/v1/workers/" + a + "/lease");
  ASSERT_EQ(r.status, 200u) << r.body;
  const std::string lease = r.js()["lease"];
  for (const std::string& secret : {b_secret, std::string("made-up"), std::string()}) {
    SCOPED_TRACE("secret '" + secret + "'");
    const std::vector<std::pair<std::string, std::string>> as{{protocol::kWorkerSecretHeader, secret}};
    for (const auto& [verb, target, body] :
         {std::tuple{http::verb::post, "/v1/leases/" + lease + "/heartbeat", std::string(R"({"rays": 5})")},
          std::tuple{http::verb::post, "/v1/leases/" + lease + "/fail", std::string(R"({"error": "sabotage"})")},
          std::tuple{http::verb::post, "/v1/leases/" + lease + "/release", std::string()},
          std::tuple{http::verb::put, "/v1/leases/" + lease + "/result", std::string("not an exr")},
          std::tuple{http::verb::get, "/v1/leases/" + lease + "/state", std::string()}}) {
      r = call(verb, target, body, as);
      EXPECT_EQ(r.status, 403u) << target << ": " << r.body;
      const std::string error = r.js().value("error", "");
      EXPECT_NE(error.find("lease " + lease + " is worker " + a + "'s"), std::string::npos) << error;
      EXPECT_EQ(error.find(a_secret), std::string::npos);
    }
    r = call(http::verb::post, "/v1/workers/" + a + "/lease", "", as);
    EXPECT_EQ(r.status, 403u) << r.body;
  }
  // Nothing changed: a's lease is live and its tile leased, no failure counted, no rays added, no tile pending again.
  const json job = call(http::verb::get, "/v1/jobs/" + id).js();
  EXPECT_EQ(job["state"], "running");
  EXPECT_EQ(job["tiles"]["leased"], 1);
  EXPECT_EQ(job["rays"], 0);
  // Each answer held in a variable: a range-for over a member of a temporary would read freed memory.
  const json before = call(http::verb::get, "/v1/jobs/" + id + "/tiles").js();
  ASSERT_FALSE(before["tiles"].empty());
  for (const json& t : before["tiles"])
    EXPECT_TRUE(t["failures"].empty()) << t.dump();
  const json workers = call(http::verb::get, "/v1/workers").js();
  ASSERT_FALSE(workers["workers"].empty());
  for (const json& w : workers["workers"])
    EXPECT_EQ(w["state"], w["id"] == a ? "rendering" : "idle") << w.dump();
  r = call(http::verb::post, "/v1/leases/" + lease + "/heartbeat");  // a, with its own secret
  EXPECT_EQ(r.status, 200u) << r.body;
  // b's own lease is b's to fail, and counts against b alone.
  r = call(http::verb::post, "/v1/workers/" + b + "/lease");
  ASSERT_EQ(r.status, 200u) << r.body;
  const std::string b_lease = r.js()["lease"];
  EXPECT_EQ(call(http::verb::post, "/v1/leases/" + b_lease + "/fail", R"({"error": "b's own"})").status, 200u);
  const json tiles = call(http::verb::get, "/v1/jobs/" + id + "/tiles").js()["tiles"];
  ASSERT_EQ(tiles[1]["failures"].size(), 1u);
  EXPECT_EQ(tiles[1]["failures"][0]["worker"], b);
}

// Registrations beyond --max-workers get 503 with Retry-After; the registered workers go on.
class WorkerBoundTest : public HttpTest {
  void configure(CoordinatorOptions& o) override { o.max_workers = 2; }
};

TEST_F(WorkerBoundTest, RegistrationsBeyondTheBoundAreRefused) {
  const std::string a = register_worker("a"), b = register_worker("b");
  const Reply r = call(http::verb::post, "/v1/workers", R"({"name": "c"})");
  EXPECT_EQ(r.status, 503u) << r.body;
  EXPECT_FALSE(std::string(r.msg[http::field::retry_after]).empty());
  EXPECT_NE(r.js().value("error", "").find("2 registered workers, its --max-workers"), std::string::npos) << r.body;
  EXPECT_EQ(call(http::verb::get, "/v1/workers").js()["workers"].size(), 2u);
  EXPECT_EQ(call(http::verb::post, "/v1/workers/" + a + "/lease").status, 204u);
}

// Registrations beyond --max-registrations-per-minute get 429 with Retry-After. At a rate of one in a million minutes
// the bucket holds one registration, whatever the machine's speed.
class RegistrationRateTest : public HttpTest {
  void configure(CoordinatorOptions& o) override { o.limits.registrations_per_minute = 1e-6; }
};

TEST_F(RegistrationRateTest, RegistrationsBeyondTheRateAreRefused) {
  const std::string a = register_worker("a");
  const Reply r = call(http::verb::post, "/v1/workers", R"({"name": "b"})");
  EXPECT_EQ(r.status, 429u) << r.body;
  EXPECT_GT(std::stoll(std::string(r.msg[http::field::retry_after])), 0);
  EXPECT_NE(r.js().value("error", "").find("--max-registrations-per-minute"), std::string::npos) << r.body;
  EXPECT_EQ(call(http::verb::get, "/v1/workers").js()["workers"].size(), 1u);
  EXPECT_EQ(call(http::verb::post, "/v1/workers/" + a + "/lease").status, 204u);
}

TEST_F(HttpTest, RegisterLeaseAndEmptyQueue) {
  const Reply reg = call(http::verb::post, "/v1/workers", R"({"name":"w","threads":2,"version":"0.1.0"})");
  ASSERT_EQ(reg.status, 201u) << reg.body;
  const std::string w = reg.js()["id"];
  EXPECT_EQ(reg.js()["lease_seconds"], 30);
  EXPECT_EQ(reg.js()["heartbeat_seconds"], 5);
  Reply r = call(http::verb::post, "/v1/workers/" + w + "/lease");
  EXPECT_EQ(r.status, 204u);
  EXPECT_TRUE(r.body.empty());
  EXPECT_EQ(call(http::verb::post, "/v1/workers/w-nobody/lease").status, 404u);
  const std::string id = submit(small_cbox(job_for("cbox_no_light.json")));
  r = call(http::verb::post, "/v1/workers/" + w + "/lease");
  ASSERT_EQ(r.status, 200u) << r.body;
  const json l = r.js();
  EXPECT_EQ(l["job"], id);
  EXPECT_EQ(l["tile"], 0);
  EXPECT_EQ(l["window"], json::array({0, 0, 16, 16}));
  EXPECT_EQ(l["spp"], 2);
  EXPECT_EQ(l["seed"], 7);
  const std::string lease = l["lease"];
  r = call(http::verb::post, "/v1/leases/" + lease + "/heartbeat", R"({"rays": 1000})");
  ASSERT_EQ(r.status, 200u) << r.body;
  EXPECT_GE(r.js()["deadline_ms"].get<int64_t>(), l["deadline_ms"].get<int64_t>());
  EXPECT_EQ(call(http::verb::post, "/v1/leases/" + lease + "/heartbeat", R"({"ray": 1})").status, 400u);
  EXPECT_EQ(call(http::verb::get, "/v1/jobs/" + id).js()["state"], "running");
  // Release hands it back; the next lease gets the same tile.
  r = call(http::verb::post, "/v1/leases/" + lease + "/release");
  EXPECT_EQ(r.status, 200u);
  EXPECT_EQ(r.js()["status"], "released");
  r = call(http::verb::post, "/v1/workers/" + w + "/lease");
  EXPECT_EQ(r.js()["tile"], 0);
  const std::string lease2 = r.js()["lease"];
  // Cancel revokes: heartbeat 410, upload 410 discarded, DELETE again 409.
  r = call(http::verb::delete_, "/v1/jobs/" + id);
  ASSERT_EQ(r.status, 200u);
  EXPECT_EQ(r.js()["state"], "cancelled");
  EXPECT_EQ(call(http::verb::post, "/v1/leases/" + lease2 + "/heartbeat").status, 410u);
  r = call(http::verb::put, "/v1/leases/" + lease2 + "/result", "not even an exr");
  EXPECT_EQ(r.status, 410u);
  EXPECT_EQ(r.js()["status"], "discarded");
  EXPECT_EQ(call(http::verb::delete_, "/v1/jobs/" + id).status, 409u);
  EXPECT_EQ(call(http::verb::get, "/v1/jobs/" + id + "/result.exr").status, 409u);
  EXPECT_EQ(call(http::verb::post, "/v1/workers/" + w + "/lease").status, 204u);
}

TEST_F(HttpTest, ALeaseCarriesItsJobsSpecUnlessTheWorkerHoldsIt) {
  const Reply reg = call(http::verb::post, "/v1/workers", R"({"name":"w","threads":2,"version":"0.1.0"})");
  ASSERT_EQ(reg.status, 201u) << reg.body;
  const std::string w = reg.js()["id"];
  const std::string lease_url = "/v1/workers/" + w + "/lease";
  const std::string id = submit(small_cbox(job_for("cbox_no_light.json")));
  const Reply spec = call(http::verb::get, "/v1/jobs/" + id + "/spec");
  ASSERT_EQ(spec.status, 200u) << spec.body;
  // Jobs known to the worker, not this one: the spec comes with the lease, as GET .../spec answers it.
  Reply r = call(http::verb::post, lease_url, R"({"known_jobs": ["j-other"]})");
  ASSERT_EQ(r.status, 200u) << r.body;
  EXPECT_EQ(r.js()["job"], id);
  EXPECT_EQ(r.js()["tile"], 0);
  EXPECT_EQ(r.js()["spec"], spec.js());
  // The worker holds it: a bare lease (the next tile).
  r = call(http::verb::post, lease_url, json{{"known_jobs", {"j-other", id}}}.dump());
  ASSERT_EQ(r.status, 200u) << r.body;
  EXPECT_EQ(r.js()["tile"], 1);
  EXPECT_FALSE(r.js().contains("spec"));
  // No list (a worker that fetches specs itself): bare as well.
  r = call(http::verb::post, lease_url);
  ASSERT_EQ(r.status, 200u) << r.body;
  EXPECT_EQ(r.js()["tile"], 2);
  EXPECT_FALSE(r.js().contains("spec"));
  // A bad request is refused before a tile is taken: the next good one gets tile 3.
  r = call(http::verb::post, lease_url, R"({"known_jobs": "all"})");
  EXPECT_EQ(r.status, 400u);
  EXPECT_NE(r.js()["error"].get<std::string>().find("known_jobs"), std::string::npos) << r.body;
  r = call(http::verb::post, lease_url, R"({"known_jobs": []})");
  ASSERT_EQ(r.status, 200u) << r.body;
  EXPECT_EQ(r.js()["tile"], 3);
  EXPECT_EQ(r.js()["spec"], spec.js());
}

// X-Tessera-Next-Lease: an upload that asks gets its worker's next lease in its answer, granted as the lease route
// grants one (its event, its spec unless known); without the header, or when it cannot be granted, the answer is
// today's.
TEST_F(HttpTest, AnUploadThatAsksCarriesItsWorkersNextLease) {
  testing::SseReader events(server_->endpoint(), "/v1/events?only=tile_leased,tile_done");
  ASSERT_EQ(events.status(), 200);
  const std::string w = register_worker("one-trip");
  const std::string id = submit(small_cbox(job_for("cbox_no_light.json")));  // 6 tiles
  const Reply spec = call(http::verb::get, "/v1/jobs/" + id + "/spec");
  const fs::path scratch = server_->data_dir() / "client";
  fs::create_directories(scratch);
  const auto tile_of = [&](const json& l) {
    const PixelWindow win{l["window"][0], l["window"][1], l["window"][2], l["window"][3]};
    return tile_exr(scratch, Image::make(win.x1 - win.x0, win.y1 - win.y0), win, 40, 30);
  };
  const auto result_url = [](const json& l) { return "/v1/leases/" + l["lease"].get<std::string>() + "/result"; };
  const auto ask = [](std::optional<std::vector<std::string>> known) {
    return std::vector<std::pair<std::string, std::string>>{
        {protocol::kNextLeaseHeader, protocol::next_lease_header(protocol::LeaseRequest{std::move(known), 0})}};
  };
  const auto tiles_pending = [&] { return call(http::verb::get, "/v1/jobs/" + id).js()["tiles"]["pending"].get<int>(); };

  Reply r = call(http::verb::post, "/v1/workers/" + w + "/lease");
  ASSERT_EQ(r.status, 200u) << r.body;
  const json l0 = r.js();
  // Asked with known_jobs that do not name the job: the next lease (tile 1) comes with the spec, as the route's would.
  r = call(http::verb::put, result_url(l0), tile_of(l0), ask(std::vector<std::string>{}));
  ASSERT_EQ(r.status, 200u) << r.body;
  EXPECT_EQ(r.js()["status"], "accepted");
  ASSERT_TRUE(r.js().contains("next")) << r.body;
  const json l1 = r.js()["next"];
  EXPECT_EQ(l1["job"], id);
  EXPECT_EQ(l1["tile"], 1);
  EXPECT_EQ(l1["spec"], spec.js());
  const auto answer = protocol::parse_answer<protocol::ResultAnswer>(r.body, "result");
  ASSERT_TRUE(answer.next);
  EXPECT_EQ(answer.next->lease.id, l1["lease"]);
  // It is a lease like any other: its heartbeat, its upload; and the job knows tile 1 leased to this worker.
  EXPECT_EQ(call(http::verb::post, "/v1/leases/" + l1["lease"].get<std::string>() + "/heartbeat").status, 200u);
  const json tiles = call(http::verb::get, "/v1/jobs/" + id + "/tiles").js();
  EXPECT_EQ(tiles["tiles"][1]["state"], "leased") << tiles.dump();
  EXPECT_EQ(tiles["tiles"][1]["worker"], w) << tiles.dump();
  // Known job: a bare lease (tile 2).
  r = call(http::verb::put, result_url(l1), tile_of(l1), ask(std::vector<std::string>{id}));
  ASSERT_EQ(r.status, 200u) << r.body;
  const json l2 = r.js()["next"];
  EXPECT_EQ(l2["tile"], 2);
  EXPECT_FALSE(l2.contains("spec"));
  // No header: exactly today's answer, and no tile taken.
  const int pending = tiles_pending();
  r = call(http::verb::put, result_url(l2), tile_of(l2));
  ASSERT_EQ(r.status, 200u) << r.body;
  EXPECT_EQ(r.body, R"({"status":"accepted"})");
  EXPECT_EQ(tiles_pending(), pending);
  // A duplicate is settled too: it asks, it gets the next tile (3).
  r = call(http::verb::put, result_url(l2), tile_of(l2), ask(std::nullopt));
  ASSERT_EQ(r.status, 200u) << r.body;
  EXPECT_EQ(r.js()["status"], "duplicate");
  const json l3 = r.js()["next"];
  EXPECT_EQ(l3["tile"], 3);
  EXPECT_EQ(tiles_pending(), pending - 1);
  // Refused uploads grant nothing: a bad header (400, before the upload is looked at), a bad tile (422).
  r = call(http::verb::put, result_url(l3), tile_of(l3), {{protocol::kNextLeaseHeader, R"({"wait_ms": 500})"}});
  EXPECT_EQ(r.status, 400u) << r.body;
  EXPECT_NE(r.js()["error"].get<std::string>().find(protocol::kNextLeaseHeader), std::string::npos) << r.body;
  EXPECT_EQ(tiles_pending(), pending - 1);
  EXPECT_EQ(call(http::verb::post, "/v1/leases/" + l3["lease"].get<std::string>() + "/heartbeat").status, 200u);
  r = call(http::verb::put, result_url(l3), "not an exr", ask(std::nullopt));
  EXPECT_EQ(r.status, 422u) << r.body;
  EXPECT_FALSE(r.js().contains("next")) << r.body;
  EXPECT_EQ(tiles_pending(), pending);  // tile 3 is pending again, nothing else taken
  // A draining worker's upload is stored, and it gets no next lease.
  r = call(http::verb::post, "/v1/workers/" + w + "/lease");
  ASSERT_EQ(r.status, 200u) << r.body;
  const json l4 = r.js();
  ASSERT_EQ(call(http::verb::post, "/v1/workers/" + w + "/drain").status, 200u);
  r = call(http::verb::put, result_url(l4), tile_of(l4), ask(std::nullopt));
  ASSERT_EQ(r.status, 200u) << r.body;
  EXPECT_EQ(r.body, R"({"status":"accepted"})");
  ASSERT_EQ(call(http::verb::post, "/v1/workers/" + w + "/undrain").status, 200u);
  // No tile left for it: the answer says nothing more, and the worker asks the lease route as usual.
  std::vector<json> held;
  while ((r = call(http::verb::post, "/v1/workers/" + w + "/lease")).status == 200) held.push_back(r.js());
  ASSERT_FALSE(held.empty());
  r = call(http::verb::put, result_url(held[0]), tile_of(held[0]), ask(std::nullopt));
  ASSERT_EQ(r.status, 200u) << r.body;
  EXPECT_EQ(r.body, R"({"status":"accepted"})");
  // A discarded upload (the job ended) grants nothing either.
  ASSERT_EQ(call(http::verb::delete_, "/v1/jobs/" + id).status, 200u);
  r = call(http::verb::put, result_url(held.back()), tile_of(held.back()), ask(std::nullopt));
  EXPECT_EQ(r.status, 410u) << r.body;
  EXPECT_EQ(r.body, R"({"status":"discarded"})");

  // The events: each next lease is a tile_leased like the lease route's, after its upload's tile_done.
  std::vector<std::pair<std::string, int64_t>> seen;
  for (int i = 0; i < 6; ++i) {
    auto e = events.next();
    ASSERT_TRUE(e) << "stream ended after " << i << " events";
    seen.emplace_back(e->event, json::parse(e->data)["tile"].get<int64_t>());
  }
  EXPECT_EQ(seen, (std::vector<std::pair<std::string, int64_t>>{{"tile_leased", 0}, {"tile_done", 0}, {"tile_leased", 1},
                                                                 {"tile_done", 1}, {"tile_leased", 2}, {"tile_done", 2}}));
}

void HttpTest::check_full_round_trip() {
  const json body = small_cbox(job_for("cbox_no_light.json"));
  const std::string id = submit(body);
  const LoadedScene local = load_local(body["scene"], 2);
  const int W = local.scene.width, H = local.scene.height;
  const std::string w1 = register_worker("one"), w2 = register_worker("two");
  const fs::path scratch = server_->data_dir() / "client";
  fs::create_directories(scratch);

  bool tried_invalid = false, tried_duplicate = false;
  int accepted = 0;
  for (int round = 0; round < 20; ++round) {
    const std::string w = round % 2 ? w2 : w1;
    Reply r = call(http::verb::post, "/v1/workers/" + w + "/lease");
    if (r.status == 204) break;
    ASSERT_EQ(r.status, 200u) << r.body;
    const json l = r.js();
    const std::string lease = l["lease"];
    const PixelWindow win{l["window"][0], l["window"][1], l["window"][2], l["window"][3]};
    EXPECT_EQ(win, TileGrid(W, H, 16).window(l["tile"].get<int64_t>()));
    RenderOptions ro;
    ro.seed = l["seed"];
    ro.spp = l["spp"];
    ro.window = win;
    const RenderResult res = render(local.scene, ro);
    EXPECT_EQ(call(http::verb::post, "/v1/leases/" + lease + "/heartbeat", json{{"rays", res.counters.rays}}.dump()).status, 200u);
    if (!tried_invalid) {
      // A tile placed at the wrong window is refused (422) and counts as this worker's failure; the tile is re-leased.
      tried_invalid = true;
      PixelWindow wrong = win;
      wrong.x0 += 1;
      wrong.x1 += 1;
      Image shifted = res.image;
      if (wrong.x1 > W) {
        wrong = {0, 0, 1, 1};
        shifted = Image::make(1, 1);
      }
      r = call(http::verb::put, "/v1/leases/" + lease + "/result", tile_exr(scratch, shifted, wrong, W, H));
      EXPECT_EQ(r.status, 422u) << r.body;
      EXPECT_NE(r.js()["error"].get<std::string>().find("window"), std::string::npos) << r.body;
      r = call(http::verb::put, "/v1/leases/" + lease + "/result", "garbage");
      EXPECT_EQ(r.status, 422u) << r.body;
      continue;
    }
    const std::string exr = tile_exr(scratch, res.image, win, W, H);
    r = call(http::verb::put, "/v1/leases/" + lease + "/result", exr, {{"X-Tessera-Rays", std::to_string(res.counters.rays)}});
    ASSERT_EQ(r.status, 200u) << r.body;
    EXPECT_EQ(r.js()["status"], "accepted");
    ++accepted;
    if (!tried_duplicate) {
      tried_duplicate = true;
      r = call(http::verb::put, "/v1/leases/" + lease + "/result", exr);
      ASSERT_EQ(r.status, 200u) << r.body;
      EXPECT_EQ(r.js()["status"], "duplicate");
      EXPECT_EQ(call(http::verb::post, "/v1/leases/" + lease + "/heartbeat").status, 410u);
      // The preview shows the partial image.
      r = call(http::verb::get, "/v1/jobs/" + id + "/preview.png");
      ASSERT_EQ(r.status, 200u);
      EXPECT_EQ(r.body.substr(1, 3), "PNG");
      EXPECT_EQ(call(http::verb::get, "/v1/jobs/" + id + "/result.exr").status, 409u);
    }
  }
  EXPECT_EQ(accepted, 6);
  const json job = call(http::verb::get, "/v1/jobs/" + id).js();
  ASSERT_EQ(job["state"], "done") << job.dump();
  EXPECT_EQ(job["tiles"]["done"], 6);
  EXPECT_FALSE(job["finished_ms"].is_null());

  const Reply exr = call(http::verb::get, "/v1/jobs/" + id + "/result.exr");
  ASSERT_EQ(exr.status, 200u);
  EXPECT_EQ(exr.msg[http::field::content_type], "image/x-exr");
  {
    std::ofstream out(scratch / "result.exr", std::ios::binary);
    out << exr.body;
  }
  const ExrImage merged = read_exr(scratch / "result.exr");
  EXPECT_EQ(merged.data_window, (PixelWindow{0, 0, W, H}));
  EXPECT_EQ(merged.display_window, (PixelWindow{0, 0, W, H}));
  EXPECT_EQ(merged.metadata.at("tessera:sceneHash"), job["scene_hash"]);
  EXPECT_EQ(merged.metadata.at("tessera:spp"), "2");
  EXPECT_EQ(merged.metadata.at("tessera:seed"), "7");
  EXPECT_EQ(merged.metadata.at("tessera:tileSize"), "16");
  RenderOptions whole;
  whole.seed = 7;
  whole.spp = 2;
  const RenderResult ref = render(local.scene, whole);
  ASSERT_EQ(merged.pixels.rgb.size(), ref.image.rgb.size());
  EXPECT_EQ(std::memcmp(merged.pixels.rgb.data(), ref.image.rgb.data(), ref.image.rgb.size() * sizeof(float)), 0);
  EXPECT_EQ(call(http::verb::get, "/v1/jobs/" + id + "/preview.png").status, 200u);
  EXPECT_EQ(call(http::verb::delete_, "/v1/jobs/" + id).status, 409u);
  const std::string metrics = call(http::verb::get, "/metrics").body;
  EXPECT_NE(metrics.find("tessera_tiles_rendered_total 6"), std::string::npos) << metrics;
  EXPECT_NE(metrics.find("tessera_jobs{state=\"done\"} 1"), std::string::npos) << metrics;
}

TEST_F(HttpTest, FullTileRoundTripIsBitwiseIdenticalToOneRender) { check_full_round_trip(); }

// A coordinator keeping its state in memory (serve --durability none, as render --workers runs it) merges the same
// bits, and keeps no database.
class HttpMemoryTest : public HttpTest {
  void configure(CoordinatorOptions& o) override { o.durability = Durability::none; }
};

TEST_F(HttpMemoryTest, FullTileRoundTripIsBitwiseIdenticalToOneRender) {
  check_full_round_trip();
  EXPECT_FALSE(fs::exists(server_->data_dir() / DurableStore::kFileName));
  EXPECT_EQ(call(http::verb::get, "/metrics").body.find("tessera_store_"), std::string::npos);  // no disk to cost
}

TEST_F(HttpTest, ThreeWorkersFailingATileFailTheJob) {
  const std::string id = submit(small_cbox(job_for("cbox_no_light.json")));
  for (const char* name : {"a", "b", "c"}) {
    const std::string w = register_worker(name);
    const Reply l = call(http::verb::post, "/v1/workers/" + w + "/lease");
    ASSERT_EQ(l.status, 200u);
    EXPECT_EQ(l.js()["tile"], 0);
    const Reply f = call(http::verb::post, "/v1/leases/" + l.js()["lease"].get<std::string>() + "/fail",
                         json{{"error", std::string("no memory on ") + name}}.dump());
    EXPECT_EQ(f.status, 200u);
    EXPECT_EQ(f.js()["status"], "recorded");
  }
  const json job = call(http::verb::get, "/v1/jobs/" + id).js();
  EXPECT_EQ(job["state"], "failed");
  EXPECT_NE(job["error"].get<std::string>().find("no memory on c"), std::string::npos) << job.dump();
  EXPECT_EQ(call(http::verb::get, "/v1/jobs/" + id + "/result.exr").status, 409u);
}

TEST_F(HttpTest, ConcurrentUploadsOfOneTileMergeItOnce) {
  json body = small_cbox(job_for("cbox_no_light.json"));
  body["tile_size"] = 64;  // one tile
  const std::string id = submit(body);
  const std::string w = register_worker();
  const json l = call(http::verb::post, "/v1/workers/" + w + "/lease").js();
  const LoadedScene local = load_local(body["scene"], 2);
  RenderOptions ro;
  ro.seed = 7;
  ro.spp = 2;
  const RenderResult res = render(local.scene, ro);
  const fs::path scratch = server_->data_dir() / "client";
  fs::create_directories(scratch);
  const std::string exr = tile_exr(scratch, res.image, res.window, local.scene.width, local.scene.height);
  std::vector<std::string> statuses(6);
  std::vector<std::thread> threads;
  for (size_t i = 0; i < statuses.size(); ++i)
    threads.emplace_back([&, i] {
      const Reply r = call(http::verb::put, "/v1/leases/" + l["lease"].get<std::string>() + "/result", exr);
      statuses[i] = r.status == 200 ? r.js()["status"].get<std::string>() : std::to_string(r.status);
    });
  for (auto& t : threads) t.join();
  EXPECT_EQ(std::count(statuses.begin(), statuses.end(), "accepted"), 1);
  EXPECT_EQ(std::count(statuses.begin(), statuses.end(), "duplicate"), 5);
  const json job = call(http::verb::get, "/v1/jobs/" + id).js();
  EXPECT_EQ(job["state"], "done");
  EXPECT_EQ(job["tiles"]["done"], 1);
  EXPECT_NE(call(http::verb::get, "/metrics").body.find("tessera_tiles_rendered_total 1\n"), std::string::npos);
}

// Leases of 0.2 s: waiting on the scheduler's own deadline, not on a timing guess about the server.
class ShortLeaseTest : public HttpTest {
 protected:
  ShortLeaseTest() { lease_seconds_ = 0.2; }
};

TEST_F(ShortLeaseTest, ExpiredLeaseIsGoneAndItsTileIsLeasedAgain) {
  const std::string id = submit(small_cbox(job_for("cbox_no_light.json")));
  const std::string a = register_worker("a"), b = register_worker("b");
  const json la = call(http::verb::post, "/v1/workers/" + a + "/lease").js();
  EXPECT_EQ(la["tile"], 0);
  // Sleep until the wall clock is past the lease's deadline.
  while (std::chrono::duration_cast<std::chrono::milliseconds>(std::chrono::system_clock::now().time_since_epoch()).count() <=
         la["deadline_ms"].get<int64_t>() + 5)
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  EXPECT_EQ(call(http::verb::post, "/v1/leases/" + la["lease"].get<std::string>() + "/heartbeat").status, 410u);
  EXPECT_NE(call(http::verb::get, "/metrics").body.find("tessera_lease_expiries_total 1\n"), std::string::npos);
  EXPECT_EQ(call(http::verb::get, "/v1/jobs/" + id).js()["tiles"]["pending"], 6);
  const Reply lb = call(http::verb::post, "/v1/workers/" + b + "/lease");
  ASSERT_EQ(lb.status, 200u);
  EXPECT_EQ(lb.js()["tile"], 0);
}

// Small limits: each answers with its status and a message naming the flag.
class LimitsTest : public HttpTest {
 protected:
  void configure(CoordinatorOptions& o) override {
    o.limits.max_queued_jobs = 2;
    o.limits.max_job_pixels = 100 * 100;
    o.limits.max_job_samples = 40 * 30 * 64;
    o.limits.max_job_frames = 2;
    o.header_limit = 4096;
  }
};

// The connection limit on its own coordinator: the other limits' tests make one connection per call, and a closed
// one may still count for a moment on a loaded machine.
class ConnectionLimitTest : public LimitsTest {
 protected:
  void configure(CoordinatorOptions& o) override {
    LimitsTest::configure(o);
    o.max_connections = 3;
  }
};

TEST_F(LimitsTest, ASequenceOverTheFrameLimitIsRefusedAndNothingIsStored) {
  const json body = small_cbox(job_for("cbox_no_light.json"));
  json seq = body;
  seq.erase("scene");
  seq["frames"] = json::array();
  for (int n = 1; n <= 3; ++n) seq["frames"].push_back({{"number", n}, {"scene", body["scene"]}});
  const Reply r = call(http::verb::post, "/v1/jobs", seq.dump());
  ASSERT_EQ(r.status, 400u) << r.body;
  EXPECT_NE(r.js()["error"].get<std::string>().find("3 frames is over the limit of 2 (--max-job-frames)"),
            std::string::npos) << r.body;
  const json jobs = call(http::verb::get, "/v1/jobs").js();
  EXPECT_TRUE(jobs["jobs"].empty()) << jobs.dump();
  // Each frame's pixels are bounded as a one-image job's: the refusal names the frame.
  seq["frames"].erase(2);
  seq["frames"][1]["scene"]["film"]["resolution"] = {101, 100};
  const Reply big = call(http::verb::post, "/v1/jobs", seq.dump());
  ASSERT_EQ(big.status, 400u) << big.body;
  EXPECT_EQ(big.js()["error"].get<std::string>().rfind("frame 2: job too large: 101x100", 0), 0u) << big.body;
  EXPECT_TRUE(call(http::verb::get, "/v1/jobs").js()["jobs"].empty());
}

TEST_F(LimitsTest, QueuedJobsPixelsAndSamples) {
  const json body = small_cbox(job_for("cbox_no_light.json"));  // 40x30 at 2 spp
  json big = body;
  big["scene"]["film"]["resolution"] = {101, 100};
  Reply r = call(http::verb::post, "/v1/jobs", big.dump());
  ASSERT_EQ(r.status, 400u);
  EXPECT_NE(r.js()["error"].get<std::string>().find("10100 pixels is over the limit of 10000 (--max-job-pixels)"), std::string::npos) << r.body;
  big = body;
  big["spp"] = 65;
  r = call(http::verb::post, "/v1/jobs", big.dump());
  ASSERT_EQ(r.status, 400u);
  EXPECT_NE(r.js()["error"].get<std::string>().find("(--max-job-samples)"), std::string::npos) << r.body;
  big = body;
  big.update(json{{"target_error", 0.1}, {"min_spp", 4}, {"max_spp", 128}});
  r = call(http::verb::post, "/v1/jobs", big.dump());
  ASSERT_EQ(r.status, 400u);
  EXPECT_NE(r.js()["error"].get<std::string>().find("x 128 max_spp"), std::string::npos) << r.body;
  big["max_spp"] = 64;
  const std::string first = submit(big);  // exactly at the sample limit
  const std::string second = submit(body);
  r = call(http::verb::post, "/v1/jobs", body.dump());
  ASSERT_EQ(r.status, 429u) << r.body;
  EXPECT_EQ(r.msg[http::field::retry_after], "30");
  EXPECT_NE(r.js()["error"].get<std::string>().find("--max-queued-jobs"), std::string::npos) << r.body;
  EXPECT_EQ(call(http::verb::delete_, "/v1/jobs/" + first).status, 200u);
  EXPECT_EQ(call(http::verb::post, "/v1/jobs", body.dump()).status, 201u);
}

TEST_F(ConnectionLimitTest, HeaderSizeAndConnections) {
  Reply r = call(http::verb::get, "/healthz", "", {{"X-Big", std::string(5000, 'x')}});
  EXPECT_EQ(r.status, 431u);
  EXPECT_NE(r.js()["error"].get<std::string>().find("limit of 4096 bytes"), std::string::npos) << r.body;
  // Three kept-alive connections fill the limit; a fourth is answered 503 without being read.
  std::vector<std::unique_ptr<Client>> open;
  for (int i = 0; i < 3; ++i) {
    open.push_back(std::make_unique<Client>(server_->endpoint()));
    ASSERT_EQ(open.back()->send(http::verb::get, "/healthz").status, 200u);
  }
  Client extra(server_->endpoint());
  r = extra.send(http::verb::get, "/healthz");
  EXPECT_EQ(r.status, 503u);
  EXPECT_EQ(r.msg[http::field::retry_after], "1");
  EXPECT_NE(r.js()["error"].get<std::string>().find("too many connections (the limit is 3)"), std::string::npos) << r.body;
  EXPECT_EQ(open[0]->send(http::verb::get, "/healthz").status, 200u);  // the served ones keep working
  open.clear();
  unsigned status = 0;
  for (int i = 0; i < 100 && status != 200; ++i) {  // the server frees the slots once it has seen the closes
    status = call(http::verb::get, "/healthz").status;
    if (status != 200) std::this_thread::sleep_for(std::chrono::milliseconds(50));
  }
  EXPECT_EQ(status, 200u);
}

TEST_F(HttpTest, HostileBodiesAndAssetPathsAreClear400s) {
  json body = small_cbox(job_for("cbox_no_light.json"));
  const std::pair<std::string, const char*> bad[] = {
      {R"({"scene": {}, "spp": 1e400})", "malformed JSON"},
      {"{\"scene\": " + std::string(100000, '['), "nested deeper than 64 levels"},
      {R"({"name": "\ud800"})", "malformed JSON"}};
  for (const auto& [text, says] : bad) {
    const Reply r = call(http::verb::post, "/v1/jobs", text);
    ASSERT_EQ(r.status, 400u) << text.substr(0, 40);
    EXPECT_NE(r.js()["error"].get<std::string>().find(says), std::string::npos) << r.body;
  }
  const std::string sha = body["assets"].begin().value();
  for (const auto& [path, says] : std::vector<std::pair<std::string, std::string>>{
           {"../floor.obj", "leaves the scene's folder"}, {"a/../../floor.obj", "leaves the scene's folder"},
           {"/etc/passwd", "absolute asset path"}}) {
    json b = body;
    b["scene"]["objects"][0]["path"] = path;
    b["assets"][path] = sha;
    const Reply r = call(http::verb::post, "/v1/jobs", b.dump());
    ASSERT_EQ(r.status, 400u) << path;
    EXPECT_NE(r.js()["error"].get<std::string>().find(says), std::string::npos) << r.body;
  }
  // An error text quoting bytes that are not UTF-8 is still a JSON error.
  const Reply r = call(http::verb::get, "/v1/jobs/\xff\xfe");
  EXPECT_EQ(r.status, 404u);
  EXPECT_NE(r.js()["error"].get<std::string>().find("no job"), std::string::npos) << r.body;
}

// ---- GET /v1/events ----

using testing::SseEvent;
using testing::SseReader;


// ?only= limits a stream to some events (what `submit -q` asks for: job events only); an unknown name is a 400.
TEST_F(HttpTest, AnEventStreamCanBeLimitedToSomeEvents) {
  SseReader jobs(server_->endpoint(), "/v1/events?only=job");
  ASSERT_EQ(jobs.status(), 200);
  const std::string w = register_worker("only");
  const std::string id = submit(small_cbox(job_for("cbox_no_light.json")));
  const json l = call(http::verb::post, "/v1/workers/" + w + "/lease").js();
  ASSERT_EQ(call(http::verb::post, "/v1/leases/" + l["lease"].get<std::string>() + "/fail", R"({"error":"boom"})").status, 200u);
  ASSERT_EQ(call(http::verb::delete_, "/v1/jobs/" + id).status, 200u);
  std::vector<std::string> states;
  for (int i = 0; i < 3; ++i) {
    auto e = jobs.next();
    ASSERT_TRUE(e) << "stream ended after " << i << " events";
    EXPECT_EQ(e->event, "job");
    states.push_back(json::parse(e->data)["state"]);
  }
  EXPECT_EQ(states, (std::vector<std::string>{"queued", "running", "cancelled"}));
  const Reply bad = call(http::verb::get, "/v1/events?only=job,tiles");
  EXPECT_EQ(bad.status, 400u) << bad.body;
  EXPECT_NE(bad.body.find("'tiles' is not an event"), std::string::npos) << bad.body;
}

TEST_F(HttpTest, EventStreamCarriesJobTileAndWorkerEventsInOrder) {
  SseReader events(server_->endpoint(), "/v1/events");
  ASSERT_EQ(events.status(), 200);
  EXPECT_NE(events.headers().find("text/event-stream"), std::string::npos) << events.headers();
  EXPECT_NE(events.headers().find("chunked"), std::string::npos) << events.headers();
  const std::string w = register_worker("ev");
  const std::string id = submit(small_cbox(job_for("cbox_no_light.json")));
  json l = call(http::verb::post, "/v1/workers/" + w + "/lease").js();
  ASSERT_EQ(call(http::verb::post, "/v1/leases/" + l["lease"].get<std::string>() + "/fail", R"({"error":"boom"})").status, 200u);
  l = call(http::verb::post, "/v1/workers/" + w + "/lease").js();
  const PixelWindow win{l["window"][0], l["window"][1], l["window"][2], l["window"][3]};
  const fs::path scratch = server_->data_dir() / "client";
  fs::create_directories(scratch);
  const std::string exr = tile_exr(scratch, Image::make(win.x1 - win.x0, win.y1 - win.y0), win, 40, 30);
  ASSERT_EQ(call(http::verb::put, "/v1/leases/" + l["lease"].get<std::string>() + "/result", exr).status, 200u);
  ASSERT_EQ(call(http::verb::delete_, "/v1/jobs/" + id).status, 200u);

  std::vector<SseEvent> got;
  for (int i = 0; i < 8; ++i) {
    auto e = events.next();
    ASSERT_TRUE(e) << "stream ended after " << i << " events";
    got.push_back(*e);
  }
  std::vector<std::string> names;
  for (const auto& e : got) names.push_back(e.event);
  EXPECT_EQ(names, (std::vector<std::string>{"worker_seen", "job", "job", "tile_leased", "tile_failed", "tile_leased",
                                             "tile_done", "job"}));
  EXPECT_EQ(json::parse(got[0].data)["reason"], "registered");
  EXPECT_EQ(json::parse(got[0].data)["worker"]["id"], w);
  EXPECT_EQ(json::parse(got[1].data)["state"], "queued");
  EXPECT_EQ(json::parse(got[1].data)["id"], id);
  EXPECT_EQ(json::parse(got[2].data)["state"], "running");
  EXPECT_EQ(json::parse(got[3].data)["tile"], 0);
  EXPECT_EQ(json::parse(got[3].data)["worker"], w);
  EXPECT_EQ(json::parse(got[4].data)["error"], "boom");
  EXPECT_EQ(json::parse(got[6].data)["job"], id);
  EXPECT_EQ(json::parse(got[6].data)["tile"], json::parse(got[5].data)["tile"]);
  EXPECT_EQ(json::parse(got[7].data)["state"], "cancelled");  // a tile done changes no job state
  // Ids are "<run>-<n>", n counting up by one.
  for (size_t i = 0; i < got.size(); ++i) {
    const std::string& gid = got[i].id;
    ASSERT_NE(gid.find('-'), std::string::npos) << gid;
    EXPECT_EQ(gid.substr(gid.find('-') + 1), std::to_string(i + 1));
  }

  // A client that reconnects with Last-Event-ID gets what came after it; one with an unknown id is told to resync.
  SseReader resumed(server_->endpoint(), "/v1/events", {{"Last-Event-ID", got[5].id}});
  for (size_t i = 6; i < got.size(); ++i) {
    const auto e = resumed.next();
    ASSERT_TRUE(e);
    EXPECT_EQ(e->id, got[i].id);
    EXPECT_EQ(e->data, got[i].data);
  }
  SseReader stale(server_->endpoint(), "/v1/events", {{"Last-Event-ID", "elsewhere-3"}});
  const auto first = stale.next();
  ASSERT_TRUE(first);
  EXPECT_EQ(first->event, "resync");
}

TEST_F(HttpTest, OperatorsDrainsRequeuesAndPurgesArePublished) {
  SseReader events(server_->endpoint(), "/v1/events");
  ASSERT_EQ(events.status(), 200);
  const std::string w = register_worker("op");
  ASSERT_EQ(call(http::verb::post, "/v1/workers/" + w + "/drain", "").status, 200u);
  ASSERT_EQ(call(http::verb::post, "/v1/workers/" + w + "/undrain", "").status, 200u);
  const std::string id = submit(small_cbox(job_for("cbox_no_light.json")));
  const json l = call(http::verb::post, "/v1/workers/" + w + "/lease").js();
  const int64_t tile = l["tile"];
  ASSERT_EQ(call(http::verb::post, "/v1/jobs/" + id + "/tiles/" + std::to_string(tile) + "/requeue", "").status, 200u);
  ASSERT_EQ(call(http::verb::delete_, "/v1/jobs/" + id).status, 200u);
  ASSERT_EQ(call(http::verb::delete_, "/v1/jobs/" + id + "?purge=true").status, 200u);

  std::vector<SseEvent> got;
  for (int i = 0; i < 9; ++i) {
    auto e = events.next();
    ASSERT_TRUE(e) << "stream ended after " << i << " events";
    got.push_back(*e);
  }
  std::vector<std::string> names;
  for (const auto& e : got) names.push_back(e.event);
  EXPECT_EQ(names, (std::vector<std::string>{"worker_seen", "worker_changed", "worker_changed", "job", "job",
                                             "tile_leased", "tile_requeued", "job", "job_removed"}));
  EXPECT_EQ(json::parse(got[1].data)["reason"], "draining");
  EXPECT_EQ(json::parse(got[1].data)["worker"]["id"], w);
  EXPECT_EQ(json::parse(got[1].data)["worker"]["state"], "draining");
  EXPECT_EQ(json::parse(got[2].data)["reason"], "undrained");
  EXPECT_EQ(json::parse(got[6].data), (json{{"job", id}, {"tile", tile}, {"worker", ""}}));
  EXPECT_EQ(json::parse(got[8].data), (json{{"id", id}, {"purged", true}, {"was", "cancelled"}}));
}

TEST_F(HttpTest, ShutdownEndsEveryEventStream) {
  SseReader a(server_->endpoint(), "/v1/events"), b(server_->endpoint(), "/v1/events");
  ASSERT_EQ(a.status(), 200);
  ASSERT_EQ(b.status(), 200);
  server_.reset();  // returns only once run() did, which needs every stream to have ended
  EXPECT_TRUE(a.ended());
  EXPECT_TRUE(b.ended());
}

class EventsTest : public HttpTest {
 protected:
  void configure(CoordinatorOptions& o) override {
    o.limits.tokens = AccessTokens{"client-token-0123456789abcdef", "worker-token-0123456789abcdef", {}};
    o.events.max_subscribers = 2;
    o.stream_idle = std::chrono::milliseconds(20);
  }
  const std::pair<std::string, std::string> client_{"Authorization", "Bearer client-token-0123456789abcdef"};
};

TEST_F(EventsTest, TokenIsCheckedStreamsAreLimitedAndIdleStreamsKeptAlive) {
  SseReader none(server_->endpoint(), "/v1/events");
  EXPECT_EQ(none.status(), 401);
  EXPECT_NE(none.body().find("token"), std::string::npos);
  SseReader worker(server_->endpoint(), "/v1/events", {{"Authorization", "Bearer worker-token-0123456789abcdef"}});
  EXPECT_EQ(worker.status(), 403);
  auto a = std::make_unique<SseReader>(server_->endpoint(), "/v1/events", std::vector{client_});
  SseReader b(server_->endpoint(), "/v1/events", {client_});
  ASSERT_EQ(a->status(), 200);
  ASSERT_EQ(b.status(), 200);
  SseReader third(server_->endpoint(), "/v1/events", {client_});
  EXPECT_EQ(third.status(), 503);
  EXPECT_NE(third.body().find("too many event streams (the limit is 2)"), std::string::npos);
  // Nothing happens: the stream still writes keep-alive comments.
  const auto idle = b.next(true);
  ASSERT_TRUE(idle);
  EXPECT_EQ(idle->event, ":");
  EXPECT_EQ(idle->data, ": keep-alive");
  // A client that goes away frees its stream: the server notices the close without writing to it.
  a->close();
  a.reset();
  int status = 0;
  for (int i = 0; i < 1000 && status != 200; ++i) {  // bounded: a broken server fails, a slow one passes
    SseReader again(server_->endpoint(), "/v1/events", {client_});
    status = again.status();
    if (status != 200) std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
  EXPECT_EQ(status, 200);
}

class DroppingEventsTest : public HttpTest {
 protected:
  void configure(CoordinatorOptions& o) override { o.events.queue_limit = 0; }  // every subscriber is "too slow"
};

TEST_F(DroppingEventsTest, ASubscriberThatFallsBehindIsDroppedAndOthersGoOn) {
  SseReader slow(server_->endpoint(), "/v1/events");
  ASSERT_EQ(slow.status(), 200);
  register_worker("w");  // publishes an event the subscriber has no room for
  EXPECT_FALSE(slow.next().has_value());
  EXPECT_TRUE(slow.ended());
  bool said = false;
  for (const auto& c : slow.comments()) said |= c.find("fell behind") != std::string::npos;
  EXPECT_TRUE(said);
  EXPECT_EQ(call(http::verb::get, "/healthz").status, 200u);  // the coordinator goes on
}

}  // namespace
}  // namespace tessera::server
