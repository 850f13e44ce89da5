// The worker's loop as `tessera worker` runs it (run_worker: two render threads, so renders begin ahead; the heartbeat
// thread; the upload thread; stop requests) against a coordinator in this process, reached through a proxy that can
// hold uploads. Built and run in the release, ASan + UBSan and TSan builds (label `worker`). Nothing here waits a
// fixed time and then checks: every wait polls for what it waits for, with a generous deadline.
#include "client/http_client.h"
#include "client/job_client.h"
#include "core/image/image.h"
#include "core/render/render.h"
#include "core/scene/scene_loader.h"
#include "core/util/file_io.h"
#include "server/test_coordinator.h"
#include "worker/recent_log.h"
#include "worker/worker.h"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>
#include <spdlog/spdlog.h>

#include <arpa/inet.h>
#include <netinet/in.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <atomic>
#include <cstring>
#include <exception>
#include <fstream>
#include <functional>
#include <memory>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

namespace tessera::worker {
namespace {

namespace fs = std::filesystem;
using namespace std::chrono_literals;
using nlohmann::json;
using protocol::JobState;

constexpr auto kDeadline = 300s;  // for anything the tests wait for: far beyond what it takes under a sanitizer

// Polls `done` every 10 ms until it is true or the deadline has passed; returns its last value.
bool eventually(const std::function<bool()>& done, std::chrono::seconds deadline = kDeadline) {
  const auto end = std::chrono::steady_clock::now() + deadline;
  while (std::chrono::steady_clock::now() < end) {
    if (done()) return true;
    std::this_thread::sleep_for(10ms);
  }
  return done();
}

// A TCP proxy on 127.0.0.1 in front of the coordinator. It forwards bytes both ways, except that while uploads are
// held it keeps every request that begins with "PUT /v1/leases/" (a tile's upload) to itself, unanswered, as a
// coordinator that is stopped or stuck would, until they are let through.
class Proxy {
 public:
  explicit Proxy(uint16_t upstream_port) : upstream_port_(upstream_port) {
    listen_fd_ = ::socket(AF_INET, SOCK_STREAM, 0);
    sockaddr_in a{};
    a.sin_family = AF_INET;
    a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    socklen_t len = sizeof a;
    if (listen_fd_ < 0 || ::bind(listen_fd_, reinterpret_cast<sockaddr*>(&a), sizeof a) != 0 ||
        ::listen(listen_fd_, 64) != 0 || ::getsockname(listen_fd_, reinterpret_cast<sockaddr*>(&a), &len) != 0)
      throw std::runtime_error(std::string("proxy: ") + std::strerror(errno));
    port_ = ntohs(a.sin_port);
    acceptor_ = std::thread([this] { accept_loop(); });
  }
  ~Proxy() {
    closing_.store(true);
    acceptor_.join();
    std::lock_guard lock(mutex_);
    for (std::thread& t : pumps_) t.join();
    ::close(listen_fd_);
  }
  Proxy(const Proxy&) = delete;
  Proxy& operator=(const Proxy&) = delete;

  std::string url() const { return "http://127.0.0.1:" + std::to_string(port_); }
  /// From now on, uploads are held (true) or let through, the ones held so far included (false).
  void hold_uploads(bool hold) { hold_.store(hold); }
  /// Uploads held so far (each counted once, when its first bytes arrived).
  int uploads_held() const { return held_.load(); }

 private:
  void accept_loop() {
    while (!closing_.load()) {
      pollfd p{listen_fd_, POLLIN, 0};
      if (::poll(&p, 1, 20) <= 0) continue;
      const int client = ::accept(listen_fd_, nullptr, nullptr);
      if (client < 0) continue;
      const int server = ::socket(AF_INET, SOCK_STREAM, 0);
      sockaddr_in a{};
      a.sin_family = AF_INET;
      a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
      a.sin_port = htons(upstream_port_);
      if (server < 0 || ::connect(server, reinterpret_cast<sockaddr*>(&a), sizeof a) != 0) {
        ::close(client);
        if (server >= 0) ::close(server);
        continue;
      }
      std::lock_guard lock(mutex_);
      pumps_.emplace_back([this, client, server] { pump(client, server); });
    }
  }

  static bool write_all(int fd, const char* data, size_t n) {
    while (n > 0) {
      const ssize_t w = ::send(fd, data, n, MSG_NOSIGNAL);
      if (w <= 0) return false;
      data += w;
      n -= size_t(w);
    }
    return true;
  }

  // Moves one connection's bytes until either side closes or the proxy stops.
  void pump(int client, int server) {
    std::string held;  // an upload's bytes kept back (a request never starts while another is held on this connection)
    char buf[1 << 16];
    while (!closing_.load()) {
      if (!held.empty() && !hold_.load()) {
        if (!write_all(server, held.data(), held.size())) break;
        held.clear();
      }
      pollfd p[2] = {{client, POLLIN, 0}, {server, POLLIN, 0}};
      if (::poll(p, 2, 20) <= 0) continue;
      if (p[0].revents) {
        const ssize_t n = ::recv(client, buf, sizeof buf, 0);
        if (n <= 0) break;
        const bool upload_starts = held.empty() && std::string_view(buf, size_t(n)).starts_with("PUT /v1/leases/");
        if (upload_starts && hold_.load()) {
          held_.fetch_add(1);
          held.append(buf, size_t(n));
        } else if (!held.empty()) {
          held.append(buf, size_t(n));
        } else if (!write_all(server, buf, size_t(n))) {
          break;
        }
      }
      if (p[1].revents) {
        const ssize_t n = ::recv(server, buf, sizeof buf, 0);
        if (n <= 0 || !write_all(client, buf, size_t(n))) break;
      }
    }
    ::close(client);
    ::close(server);
  }

  uint16_t upstream_port_ = 0, port_ = 0;
  int listen_fd_ = -1;
  std::atomic<bool> closing_{false}, hold_{false};
  std::atomic<int> held_{0};
  std::mutex mutex_;
  std::vector<std::thread> pumps_;  // guarded by mutex_
  std::thread acceptor_;            // last: starts once the rest is ready
};

// run_worker on a thread of its own, with its own stop counter.
class WorkerThread {
 public:
  explicit WorkerThread(WorkerOptions o) : options_(std::move(o)) {
    thread_ = std::thread([this] {
      try {
        stats_ = run_worker(options_, stop_);
      } catch (...) {
        error_ = std::current_exception();
      }
      finished_.store(true);
    });
  }
  ~WorkerThread() {
    if (!thread_.joinable()) return;
    stop_.store(2);
    thread_.join();
  }
  WorkerThread(const WorkerThread&) = delete;
  WorkerThread& operator=(const WorkerThread&) = delete;

  /// One more stop request (as SIGTERM would make).
  void request_stop() { stop_.fetch_add(1); }
  bool finished() const { return finished_.load(); }
  /// Waits for run_worker to return (failing the test past the deadline) and gives its stats.
  WorkerStats join() {
    EXPECT_TRUE(eventually([&] { return finished(); })) << "the worker did not stop";
    if (!finished()) stop_.store(2);  // the test has failed: the thread is not left running
    thread_.join();
    if (error_) std::rethrow_exception(error_);
    return stats_;
  }

 private:
  WorkerOptions options_;
  std::atomic<int> stop_{0};
  std::atomic<bool> finished_{false};
  WorkerStats stats_;          // written by the thread before finished_
  std::exception_ptr error_;   // likewise
  std::thread thread_;         // last
};

class WorkerLoop : public ::testing::Test {
 protected:
  void SetUp() override {
    spdlog::set_level(spdlog::level::warn);
    dir_ = fs::temp_directory_path() / ("tessera-worker-loop-test-" + random_hex(6));
    fs::create_directories(dir_);
  }
  void TearDown() override {
    proxy_.reset();
    coordinator_.reset();
    std::error_code ec;
    fs::remove_all(dir_, ec);
  }

  // A coordinator announcing 1 s heartbeats, with the given lease length, and the proxy in front of it.
  void start_coordinator(double lease_seconds = 30, size_t header_limit = server::CoordinatorOptions{}.header_limit) {
    server::CoordinatorOptions o;
    o.header_limit = header_limit;
    o.durability = server::Durability::none;
    o.handler_threads = 2;
    o.limits.heartbeat_seconds = 1;
    o.lease_seconds = lease_seconds;
    coordinator_ = std::make_unique<server::testing::RunningCoordinator>(o, "worker-loop");
    proxy_ = std::make_unique<Proxy>(coordinator_->endpoint().port());
    http_ = std::make_unique<client::HttpClient>(
        client::parse_http_url("http://127.0.0.1:" + std::to_string(coordinator_->endpoint().port())));
  }

  // A worker through the proxy with two render threads (renders begin ahead of their tile's lease round trip).
  WorkerOptions worker_options(const std::string& name) const {
    WorkerOptions o;
    o.coordinator = proxy_->url();
    o.threads = 2;
    o.cache_dir = dir_ / ("cache-" + name);
    o.name = name;
    o.max_idle_wait = 200ms;
    o.max_retry_wait = 500ms;
    return o;
  }

  // A small analytic scene (no assets) of width x height pixels.
  fs::path write_scene(int width, int height) {
    const json scene = {
        {"integrator", {{"type", "intersection_test"}, {"spp", 1}, {"point_light_position", {0, 3, 3}},
                        {"point_light_flux", {40, 40, 40}}}},
        {"film", {{"resolution", {width, height}}}},
        {"camera", {{"position", {0, 0.3, 4}}, {"look_at", {0, 0, 0}}, {"fov", 45}}},
        {"textures", {{"white", {{"type", "constant"}, {"color", {0.8, 0.7, 0.6}}}},
                      {"blue", {{"type", "constant"}, {"color", {0.2, 0.3, 0.9}}}}}},
        {"materials", {{"m", {{"type", "diffuse"}, {"texture_name", "white"}}},
                       {"b", {{"type", "diffuse"}, {"texture_name", "blue"}}}}},
        {"objects", {{{"type", "sphere"}, {"center", {-0.6, 0, 0}}, {"radius", 0.7}, {"material_name", "m"}},
                     {{"type", "sphere"}, {"center", {0.7, 0, 0.3}}, {"radius", 0.5}, {"material_name", "m"}},
                     {{"type", "sphere"}, {"center", {0, -101, 0}}, {"radius", 100}, {"material_name", "b"}}}}};
    const fs::path p = dir_ / ("scene-" + random_hex(4) + ".json");
    std::ofstream(p) << scene.dump();
    return p;
  }

  // Submits the scene of a width x height image in tiles of `tile` pixels at `spp`; gives the job id.
  std::string submit(int width, int height, int tile, uint32_t spp) {
    client::SubmitOptions s;
    s.scene = write_scene(width, height);
    s.sampling.spp = spp;
    s.sampling.seed = 11;
    s.tile_size = tile;
    return client::submit_job(*http_, s).job_id;
  }

  protocol::JobStatus job(const std::string& id) { return client::get_job(*http_, id); }

  // Waits for the job to end; gives its last status.
  protocol::JobStatus wait_ended(const std::string& id) {
    protocol::JobStatus s;
    EXPECT_TRUE(eventually([&] { return (s = job(id)).finished(); })) << "job " << id << " did not end";
    return s;
  }

  // Checks that the finished job's image is bitwise the image of one render of its spec in this process.
  void expect_bitwise_one_render(const std::string& id) {
    const protocol::JobSpec spec = client::get_job_spec(*http_, id);
    const fs::path result = dir_ / (id + ".exr");
    client::download_result(*http_, id, result);
    const ExrImage merged = read_exr(result);
    const LoadedScene local = load_scene_json(
        spec.scene, "scene", [](const std::string& p, const std::string&) -> fs::path { throw std::runtime_error("asset " + p); },
        spec.sampling.load_options());
    RenderOptions ro;
    spec.sampling.apply_to(ro);
    ro.spp = spec.sampling.spp;
    const RenderResult ref = render(local.scene, ro);
    ASSERT_EQ(merged.pixels.rgb.size(), ref.image.rgb.size());
    EXPECT_EQ(std::memcmp(merged.pixels.rgb.data(), ref.image.rgb.data(), ref.image.rgb.size() * sizeof(float)), 0)
        << "the farm's image differs from one render's";
  }

  // Every tile of the job is done, each rendered by one lease.
  void expect_each_tile_rendered_once(const std::string& id) {
    for (const protocol::TileInfo& t : client::get_job_tiles(*http_, id).tiles) {
      EXPECT_EQ(t.state, "done") << "tile " << t.index;
      EXPECT_EQ(t.attempts, 1) << "tile " << t.index;
    }
  }

  fs::path dir_;
  std::unique_ptr<server::testing::RunningCoordinator> coordinator_;
  std::unique_ptr<Proxy> proxy_;
  std::unique_ptr<client::HttpClient> http_;  // the test's own connection, straight to the coordinator
};

TEST_F(WorkerLoop, RendersEveryTileOnceBitwiseLikeOneRender) {
  start_coordinator();
  const std::string id = submit(64, 48, 16, 8);  // 4x3 tiles
  WorkerThread w(worker_options("w1"));
  const protocol::JobStatus s = wait_ended(id);
  ASSERT_EQ(s.state, JobState::done);
  w.request_stop();
  const WorkerStats stats = w.join();
  EXPECT_EQ(stats.tiles_uploaded, 12);
  EXPECT_EQ(stats.tiles_dropped + stats.tiles_failed + stats.tiles_released, 0);
  expect_each_tile_rendered_once(id);
  expect_bitwise_one_render(id);
}

// Each upload carries the worker's log lines about its lease, kept with the done tile; behind a coordinator whose
// header limit is below a log's size, the upload goes again without the log, and no tile is lost.
TEST_F(WorkerLoop, UploadsCarryTheirLogLinesAndGoWithoutThemWhenTheHeaderIsTooLarge) {
  spdlog::set_level(spdlog::level::info);  // the lines a tile's log is made of
  for (const size_t header_limit : {server::CoordinatorOptions{}.header_limit, size_t(450)}) {
    SCOPED_TRACE("header limit " + std::to_string(header_limit));
    start_coordinator(30, header_limit);
    const std::string id = submit(32, 16, 16, 1);  // 2 tiles
    WorkerThread w(worker_options("w1"));
    ASSERT_EQ(wait_ended(id).state, JobState::done);
    w.request_stop();
    EXPECT_EQ(w.join().tiles_uploaded, 2);
    for (const protocol::TileInfo& t : client::get_job_tiles(*http_, id).tiles) {
      if (header_limit == size_t(450)) {
        EXPECT_TRUE(t.log.empty()) << "tile " << t.index;
        continue;
      }
      ASSERT_FALSE(t.log.empty()) << "tile " << t.index;
      EXPECT_NE(t.log.front().find("tile=" + std::to_string(t.index) + " lease="), std::string::npos) << t.log.front();
      EXPECT_NE(t.log.back().find("rendered in"), std::string::npos) << t.log.back();
    }
    proxy_.reset();
    coordinator_.reset();
  }
}

// A stop request mid-job: the worker finishes and uploads its tile, hands back the one it was given next, and
// returns; no tile stays leased to it, and a second worker finishes the job with the same bits.
TEST_F(WorkerLoop, StopMidJobUploadsItsTileHandsTheNextBackAndReturns) {
  start_coordinator();
  const std::string id = submit(96, 64, 16, 512);  // 6x4 tiles
  WorkerStats first;
  {
    WorkerThread w(worker_options("w1"));
    ASSERT_TRUE(eventually([&] { return job(id).tiles.done >= 1; }));
    w.request_stop();
    first = w.join();
  }
  const protocol::JobStatus after = job(id);
  EXPECT_EQ(after.tiles.leased, 0) << "a tile stayed leased to the stopped worker";
  EXPECT_EQ(after.tiles.done, first.tiles_uploaded);
  EXPECT_EQ(first.tiles_dropped + first.tiles_failed, 0);
  if (after.tiles.done < after.tiles.total) {
    WorkerThread w2(worker_options("w2"));
    ASSERT_EQ(wait_ended(id).state, JobState::done);
    w2.request_stop();
    const WorkerStats second = w2.join();
    EXPECT_EQ(first.tiles_uploaded + second.tiles_uploaded, 24);
  }
  expect_bitwise_one_render(id);
}

// A job cancelled while its tile renders: the heartbeat (or the upload) is answered 410, the worker drops the tile
// and goes on to the next job, which it renders whole. The cancel comes once two heartbeats have reported the
// render's rays, so the heartbeat thread and the render have run side by side.
TEST_F(WorkerLoop, CancelledJobsTileIsDroppedAndTheNextJobRenders) {
  start_coordinator();
  // Long enough (16 tiles of 64x64 at 4096 spp) that it is cancelled long before it could end.
  const std::string long_job = submit(256, 256, 64, 4096);
  WorkerThread w(worker_options("w1"));
  uint64_t rays = 0;
  ASSERT_TRUE(eventually([&] { return (rays = job(long_job).rays) > 0; }));
  ASSERT_TRUE(eventually([&] { return job(long_job).rays > rays; }));
  ASSERT_TRUE(client::cancel_job(*http_, long_job));
  const int64_t done_before_cancel = job(long_job).tiles.done;
  const std::string next = submit(64, 48, 16, 8);
  ASSERT_EQ(wait_ended(next).state, JobState::done);
  EXPECT_EQ(job(long_job).state, JobState::cancelled);
  // The dropped tile is counted before the worker asks for more work, and the next job's tiles came after it.
  w.request_stop();
  const WorkerStats stats = w.join();
  EXPECT_GE(stats.tiles_dropped, 1);
  EXPECT_EQ(stats.tiles_uploaded, 12 + done_before_cancel);
  EXPECT_EQ(stats.tiles_failed, 0);
  expect_each_tile_rendered_once(next);
  expect_bitwise_one_render(next);
}

// An upload the coordinator holds goes through once it lets it: holding stalls the pipeline, it loses nothing.
TEST_F(WorkerLoop, HeldUploadGoesThroughWhenLet) {
  start_coordinator();
  proxy_->hold_uploads(true);
  const std::string id = submit(32, 32, 16, 4);  // 2x2 tiles
  WorkerThread w(worker_options("w1"));
  ASSERT_TRUE(eventually([&] { return proxy_->uploads_held() >= 1; }));
  EXPECT_EQ(job(id).tiles.done, 0);
  proxy_->hold_uploads(false);
  ASSERT_EQ(wait_ended(id).state, JobState::done);
  w.request_stop();
  const WorkerStats stats = w.join();
  EXPECT_EQ(stats.tiles_uploaded, 4);
  expect_each_tile_rendered_once(id);
  expect_bitwise_one_render(id);
}

// A render that ends without the next lease in hand (there was no other work when the worker asked for it) asks for
// it with its upload: work that comes while the upload is under way is leased in the upload's answer, with no lease
// request of its own, and rendered from it.
TEST_F(WorkerLoop, AnUploadWithoutANextLeaseInHandAsksForItAndTheWorkerRendersIt) {
  spdlog::set_level(spdlog::level::info);  // the lines a tile's log is made of
  start_coordinator();
  proxy_->hold_uploads(true);
  const std::string first = submit(16, 16, 16, 4);  // one tile: the request for the next lease gets none
  WorkerThread w(worker_options("w1"));
  ASSERT_TRUE(eventually([&] { return proxy_->uploads_held() >= 1; }));
  const std::string second = submit(32, 16, 16, 4);  // two tiles, submitted while the upload is held
  proxy_->hold_uploads(false);
  ASSERT_EQ(wait_ended(first).state, JobState::done);
  ASSERT_EQ(wait_ended(second).state, JobState::done);
  w.request_stop();
  const WorkerStats stats = w.join();
  EXPECT_EQ(stats.tiles_uploaded, 3);
  EXPECT_EQ(stats.tiles_dropped + stats.tiles_failed + stats.tiles_released, 0);
  // The second job's first tile came with the first job's upload (its log says so); its other tile as usual.
  const std::vector<protocol::TileInfo> tiles = client::get_job_tiles(*http_, second).tiles;
  int with_upload = 0;
  for (const protocol::TileInfo& t : tiles)
    for (const std::string& line : t.log) with_upload += line.find("granted with the upload of the previous tile") != std::string::npos;
  EXPECT_EQ(with_upload, 1);
  expect_each_tile_rendered_once(second);
  expect_bitwise_one_render(second);
}

// A stopping worker whose last upload the coordinator holds gives it up and returns; `why` is the reason it logs.
// (Should the tile's lease run out before the stop request arrives, the worker leases the tile again and gives up
// that upload too: each upload given up is one line.)
class HeldUploadOnStop : public WorkerLoop {
 protected:
  void expect_given_up(WorkerOptions o, int stop_requests, const std::string& why) {
    RecentLogScope log;  // the give-up is logged as a warning
    proxy_->hold_uploads(true);
    const std::string id = submit(16, 16, 16, 4);  // one tile
    WorkerThread w(std::move(o));
    ASSERT_TRUE(eventually([&] { return proxy_->uploads_held() >= 1; }));
    for (int i = 0; i < stop_requests; ++i) w.request_stop();
    const WorkerStats stats = w.join();
    EXPECT_EQ(stats.tiles_uploaded, 0);
    const std::vector<std::string> lines = log.log().lines_with("giving up the upload of tile 0 of job " + id, 10, 1000);
    ASSERT_GE(lines.size(), 1u);
    EXPECT_EQ(stats.tiles_dropped, int64_t(lines.size()));
    for (const std::string& line : lines) EXPECT_NE(line.find(why), std::string::npos) << line;
    EXPECT_EQ(job(id).tiles.done, 0);
  }
};

TEST_F(HeldUploadOnStop, AfterTheStopTimeout) {
  start_coordinator();
  WorkerOptions o = worker_options("w1");
  o.stop_timeout = 500ms;
  expect_given_up(o, 1, "not taken it within --stop-timeout");
}

TEST_F(HeldUploadOnStop, OnASecondStopRequest) {
  start_coordinator();
  WorkerOptions o = worker_options("w1");
  o.stop_timeout = 3600s;
  expect_given_up(o, 2, "asked to stop again");
}

TEST_F(HeldUploadOnStop, OnceItsLeaseRanOut) {
  start_coordinator(3);
  WorkerOptions o = worker_options("w1");
  o.stop_timeout = 3600s;
  expect_given_up(o, 1, "its lease ran out");
}

}  // namespace
}  // namespace tessera::worker
