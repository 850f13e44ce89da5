#include "cli/render_farm.h"

#include "cli/exit_status.h"
#include "cli/farm_log.h"
#include "cli/frame_list.h"
#include "cli/interrupt_guard.h"
#include "cli/output_check.h"
#include "cli/private_coordinator.h"
#include "cli/submit_command.h"
#include "cli/worker_command.h"
#include "core/image/exr_multipart.h"
#include "core/image/image.h"
#include "core/render/layer_film.h"
#include "server/auth.h"
#include "server/coordinator_store.h"
#include "server/storage.h"
#include "core/util/file_io.h"
#include "core/util/remove_tree.h"
#include "core/util/sha256.h"
#include "core/scene/scene_loader.h"
#include "worker/arena_pinning.h"
#include "worker/child_process.h"
#include "client/http_client.h"

#include <spdlog/sinks/ansicolor_sink.h>
#include <spdlog/spdlog.h>

#include <arpa/inet.h>
#include <fcntl.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <csignal>
#include <cstdlib>
#include <cstring>
#include <optional>
#include <string>
#include <thread>
#include <utility>
#include <vector>

namespace tessera::cli {

namespace fs = std::filesystem;
using namespace std::chrono_literals;

namespace {

// Longest wait of a private farm's idle worker between lease requests (a shared coordinator's workers wait up to 2 s).
constexpr int kPrivateIdleWaitMs = 5;

// The scene or its assets could not be read; the reason was logged (exit status kExitRefused).
struct Refused : std::exception {};

// Writes a fresh random token to a file only this user can read and returns the token.
std::string write_token_file(const fs::path& path) {
  const std::string token = server::generate_token();
  const int fd = ::open(path.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0600);
  if (fd < 0) throw std::runtime_error("cannot create " + path.string());
  const std::string line = token + "\n";
  const bool ok = ::write(fd, line.data(), line.size()) == ssize_t(line.size());
  ::close(fd);
  if (!ok) throw std::runtime_error("cannot write " + path.string());
  return token;
}

fs::path make_temp_dir() {
  const char* base = std::getenv("TMPDIR");
  std::string pattern = std::string(base && *base ? base : "/tmp") + "/tessera-render-XXXXXX";
  if (!::mkdtemp(pattern.data())) throw std::runtime_error("cannot create a temporary folder: " + std::string(std::strerror(errno)));
  return pattern;
}

// A TCP socket listening on a free loopback port (close-on-exec), and that port: the coordinator is started on it, so
// the workers and the submission need not wait for it to tell its address, and connect while it starts.
std::pair<int, unsigned short> listen_on_loopback() {
  const int fd = ::socket(AF_INET, SOCK_STREAM | SOCK_CLOEXEC, 0);
  if (fd < 0) throw std::runtime_error(std::string("cannot create a socket: ") + std::strerror(errno));
  sockaddr_in addr{};
  addr.sin_family = AF_INET;
  addr.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  addr.sin_port = 0;
  socklen_t len = sizeof addr;
  if (::bind(fd, reinterpret_cast<sockaddr*>(&addr), sizeof addr) != 0 || ::listen(fd, SOMAXCONN) != 0 ||
      ::getsockname(fd, reinterpret_cast<sockaddr*>(&addr), &len) != 0) {
    const int err = errno;
    ::close(fd);
    throw std::runtime_error(std::string("cannot listen on a loopback port: ") + std::strerror(err));
  }
  return {fd, ntohs(addr.sin_port)};
}

// The pipes that hand the workers the job they are about to be leased (worker --preload reads its file to the end): a
// worker is given a read end when it starts, the job is written to every write end once its assets are stored, and
// the write ends are closed then, or on the way out (an empty pipe preloads nothing).
class PreloadPipes {
 public:
  PreloadPipes() = default;
  ~PreloadPipes() { close(); }
  PreloadPipes(const PreloadPipes&) = delete;
  PreloadPipes& operator=(const PreloadPipes&) = delete;

  /// A new pipe's read end for the next worker (close-on-exec here; fork_child and spawn_child keep it open for the
  /// worker), or -1 when none can be made.
  int open() {
    int fds[2];
    if (::pipe2(fds, O_CLOEXEC) != 0) return -1;
    pending_read_ = fds[0];
    writes_.push_back(fds[1]);
    return fds[0];
  }
  /// The worker has started with its read end: this process's copy goes.
  void spawned() {
    if (pending_read_ >= 0) ::close(pending_read_);
    pending_read_ = -1;
  }
  /// Writes `job` whole to every pipe that can hold it (a job larger than a pipe can be made is not preloaded).
  void send(const std::string& job) {
    for (const int fd : writes_) {
      if (job.size() > kDefaultPipeBytes) ::fcntl(fd, F_SETPIPE_SZ, int(std::min<size_t>(job.size(), kMaxPipeBytes)));
      const int capacity = ::fcntl(fd, F_GETPIPE_SZ);
      if (capacity < 0 || size_t(capacity) < job.size()) continue;
      // The pipe is empty and holds it all: no wait for the reader. A worker already gone (EPIPE) reads nothing.
      write_all(fd, job);
    }
  }
  /// Ends every pipe: the workers read what was sent, or nothing.
  void close() {
    spawned();
    for (const int fd : writes_) ::close(fd);
    writes_.clear();
  }

 private:
  static constexpr size_t kDefaultPipeBytes = 65536, kMaxPipeBytes = size_t(1) << 20;
  int pending_read_ = -1;
  std::vector<int> writes_;
};

// `tessera worker` as a child of this process started with exec: the command line of `w`'s fields that
// run_render_farm sets.
std::vector<std::string> worker_command_line(const std::string& self, const WorkerArgs& w) {
  std::vector<std::string> argv{self, "worker", "--coordinator", w.coordinator, "--threads", std::to_string(w.threads),
                                "--cache", w.cache, "--name", w.name, "--token-file", w.token_file,
                                "--max-idle-wait-ms", std::to_string(w.max_idle_wait_ms)};
  if (!w.preload.empty()) argv.insert(argv.end(), {"--preload", w.preload});
  if (!w.cpus.empty()) argv.insert(argv.end(), {"--cpus", w.cpus});
  const std::vector<std::string> limits = asset_limit_args(w.asset_limits);
  argv.insert(argv.end(), limits.begin(), limits.end());
  return argv;
}

// `tessera worker` in a forked copy of this process, with the logger a new process starts with (this command's
// colours the lines for its terminal).
int run_forked_worker(const WorkerArgs& w) {
  spdlog::set_default_logger(
      std::make_shared<spdlog::logger>("", std::make_shared<spdlog::sinks::ansicolor_stdout_sink_mt>()));
  const int rc = run_worker_command(w);
  spdlog::default_logger()->flush();
  return rc;
}

// Starts `a.workers` workers of the private farm at `url` with `dir` as their cache, appending them to `workers` as
// they start (so that those started are stopped should a later one fail), each handed a pipe of `preloads` when
// given; returns the render threads each has. Until the job is in they ask for work every few milliseconds (a
// private farm's coordinator has nothing else to do), so the first lease follows the job's acceptance at once. From
// a single-threaded process each is a forked copy of it; otherwise `tessera worker` started with exec.
int start_workers(const RenderArgs& a, const std::string& url, const fs::path& dir, PreloadPipes* preloads,
                  std::vector<worker::ChildProcess>& workers) {
  const unsigned cores = std::max(1u, std::thread::hardware_concurrency());
  const int threads = a.threads > 0 ? a.threads : std::max(1, int(cores) / a.workers);
  // When the workers' threads fit the CPUs this command may use, each thread gets its own.
  const std::vector<int> cpus = worker::allowed_cpus();
  const bool pin = size_t(a.workers) * size_t(threads) <= cpus.size();
  const bool fork_workers = worker::single_threaded();  // not under ThreadSanitizer, whose own thread runs too
  for (int i = 0; i < a.workers; ++i) {
    WorkerArgs w;
    w.coordinator = url;
    w.threads = threads;
    w.cache = (dir / "data").string();
    w.name = "local-" + std::to_string(i);
    w.token_file = (dir / "worker.token").string();
    w.max_idle_wait_ms = kPrivateIdleWaitMs;
    w.asset_limits = a.asset_limits;
    for (int t = 0; pin && t < threads; ++t) w.cpus += (t ? "," : "") + std::to_string(cpus[size_t(i * threads + t)]);
    const int preload_fd = preloads ? preloads->open() : -1;
    if (preload_fd >= 0) w.preload = "/dev/fd/" + std::to_string(preload_fd);
    const std::string name = "worker " + std::to_string(i);
    const fs::path log = dir / ("worker-" + std::to_string(i) + ".log");
    workers.push_back(fork_workers ? worker::fork_child([w] { return run_forked_worker(w); }, name, log, preload_fd,
                                                        "tessera-worker")
                                   : worker::spawn_child(worker_command_line(fs::read_symlink("/proc/self/exe").string(), w),
                                                         name, log, preload_fd));
    if (preloads) preloads->spawned();
  }
  return threads;
}

// Copies each asset of `files` into the private coordinator's blob folder under `dir`, which is also the workers'
// cache (the same layout, DIR/blobs/<2 hex digits>/<sha256>): the submission finds them stored instead of uploading
// each one, and the workers find them cached instead of fetching each one. One copy serves both, so the scratch
// folder has fewer entries to make and to remove. Throws client::SubmitError for a file that changed since it was
// hashed; an asset that cannot be stored goes to the coordinator by upload.
void store_assets(const client::SceneFiles& files, const fs::path& dir) {
  const fs::path blobs = server::blobs_dir(dir / "data");
  const auto store = [&](const client::LocalAsset& asset) {
    const fs::path stored = server::blob_file(blobs, asset.sha256);
    std::error_code ec;
    if (fs::exists(stored, ec)) return;  // the same bytes under another name
    const std::string bytes = read_file_bytes(asset.file);
    if (sha256_hex(bytes) != asset.sha256) throw client::SubmitError(asset.path + " changed while it was read");
    // Staged outside the blob folders and renamed in whole: the starting coordinator clears temp files there.
    const fs::path staged = dir / ("staged-" + asset.sha256);
    write_file_atomic(staged, bytes, Flush::none);
    fs::create_directories(stored.parent_path(), ec);
    if (!ec) fs::rename(staged, stored, ec);
    if (ec) {
      spdlog::debug("{} goes to the coordinator by upload: {}", asset.path, ec.message());
      fs::remove(staged, ec);
    }
  };
  for (const client::LocalAsset& asset : files.assets) store(asset);
  for (const client::FrameFiles& frame : files.frames)
    for (const client::LocalAsset& asset : frame.assets) store(asset);
}

// The done job's result is a file in the private coordinator's folder, which this command owns and throws away: it is
// moved to `output` (synced first, as a download would have been written) or copied when `output` is on another file
// system, instead of being sent over HTTP and written again.
uint64_t take_result(const fs::path& data_dir, const std::string& job, const fs::path& output) {
  const fs::path file = server::job_result_file(data_dir, job);
  const uint64_t size = fs::file_size(file);
  move_file_atomic(file, output);
  return size;
}

// Writes the --half or --multipart copy and the --preview PNG of a finished image, as a render in one process would
// have.
void finish_output(const RenderArgs& a, const std::string& output, const std::string& preview) {
  if (!a.half && !a.multipart && preview.empty()) return;
  const ExrImage img = read_exr(output);
  if (a.half || a.multipart) {
    ExrWriteOptions wo;
    wo.half = a.half;
    wo.data_window = img.data_window;
    wo.display_window = img.display_window;
    wo.metadata = img.metadata;
    if (a.multipart) write_exr_multipart(output, img.pixels, wo, layer_parts(img.pixels));
    else write_exr(output, img.pixels, wo);
  }
  if (!preview.empty()) write_png_srgb(preview, img.pixels);
}

}  // namespace

int run_render_farm(const RenderArgs& a, const std::vector<client::FrameScene>& frames) {
  if (!a.crop.empty() || a.variance) {
    spdlog::error("--workers renders whole images without --variance (ask for --layers variance): drop --crop/--variance");
    return kExitRefused;
  }
  // --strict is a property of loading the file here, which the coordinator does not repeat: refused, never dropped.
  if (a.strict) {
    spdlog::error("--workers does not pass on --strict: check the scene with `tessera render --strict` first");
    return kExitRefused;
  }
  InterruptGuard guard;
  std::signal(SIGPIPE, SIG_IGN);  // a worker that dies before it reads its job must not take this command with it
  std::vector<worker::ChildProcess> workers;
  std::optional<FarmLog> farm_log;
  std::optional<PrivateCoordinator> coordinator;
  fs::path dir;
  int rc = kExitFailed;
  bool show_logs = false;
  try {
    dir = make_temp_dir();
    // Fresh tokens per render: other users of this machine cannot submit to or pose as workers of this farm.
    const std::string client_token = server::generate_token();
    const std::string worker_token = write_token_file(dir / "worker.token");
    // The private coordinator serves on a socket bound here, so that its address is known at once and the workers and
    // the submission connect while it starts.
    auto [listen_fd, port] = listen_on_loopback();
    struct CloseUnlessTaken {
      int& fd;
      ~CloseUnlessTaken() { if (fd >= 0) ::close(fd); }
    } listening{listen_fd};  // until the coordinator takes it
    const std::string url = "http://127.0.0.1:" + std::to_string(port);
    // The workers start first, while this process has no other thread: each is a copy of it (fork without exec, nothing
    // to load and link), which runs `tessera worker` while the scene's assets are read here and the job is submitted.
    PreloadPipes preloads;
    const int threads = start_workers(a, url, dir, frames.empty() ? &preloads : nullptr, workers);
    // The private coordinator runs on threads of this process (its log in serve.log): it keeps its jobs in memory and
    // never waits for the disk, since its folder is thrown away with this command. Its one job is refused only by a
    // full disk, not by a floor of free space.
    farm_log.emplace(dir / "serve.log");
    server::CoordinatorOptions co;
    co.listen_fd = std::exchange(listen_fd, -1);  // the coordinator's from here on
    co.data_dir = dir / "data";
    co.durability = server::Durability::none;
    co.min_free_disk = 0;
    co.limits.tokens.client = client_token;
    co.limits.tokens.worker = worker_token;
    co.limits.assets = a.asset_limits;
    coordinator.emplace(std::move(co));
    client::SubmitOptions o = shared_job_options(a);
    o.frames = frames;
    o.frame_order = protocol::frame_order_from_string(a.frame_order);
    o.tile_size = a.farm_tile;
    o.resumable = a.resumable;  // the result then carries the state channels, as `render --resumable` writes them
    // While the coordinator starts: the scene's assets are hashed and stored where the coordinator and the workers
    // look for them.
    std::optional<client::SceneFiles> files;
    try {
      files = client::read_scene_files(o);
      store_assets(*files, dir);
    } catch (const SceneError& e) {
      spdlog::error("{}", e.what());
      rc = kExitRefused;
    } catch (const client::SubmitError& e) {
      spdlog::error("{}", e.what());
      rc = kExitRefused;
    }
    if (rc == kExitRefused) throw Refused();
    // The workers load the job's scene from their cache while the coordinator checks the submission. (A sequence's
    // frames are loaded as they are leased.)
    if (frames.empty()) preloads.send(nlohmann::json(client::job_submission(o, *files)).dump());
    preloads.close();
    client::HttpClient http(client::parse_http_url(url));
    http.set_bearer_token(client_token);
    if (!a.quiet)
      std::fprintf(stderr, "coordinator on %s, %d worker(s) with %d thread(s) each\n", url.c_str(), a.workers, threads);
    rc = submit_and_wait(
        http, o, a.output, a.quiet,
        [&] {
          if (InterruptGuard::interrupted()) return true;
          // Every worker gone, or the coordinator, means no progress is possible.
          bool all_workers_gone = !workers.empty();
          for (auto& w : workers) all_workers_gone &= worker::child_exited(w);
          return all_workers_gone || coordinator->ended();
        },
        std::move(files),
        [&](const std::string& job, const std::string& output, int64_t frame) {
          const uint64_t size = take_result(dir / "data", job, output);
          if (!frames.empty())  // a frame: its preview goes to the frame's file of the --preview pattern
            finish_output(a, output, a.preview.empty() ? "" : frame_output(a.preview, frame, frames.size()).string());
          return size;
        });
    if (rc == 0 && frames.empty()) finish_output(a, a.output, a.preview);
    if (InterruptGuard::interrupted()) {
      spdlog::warn("interrupted");
      rc = kExitInterrupted;
    }
    show_logs = rc == kExitFailed;  // not when the coordinator refused the job and said why, nor when interrupted
  } catch (const Refused&) {
    // said why already (rc is kExitRefused)
  } catch (const std::exception& e) {
    spdlog::error("render --workers: {}", e.what());
    rc = kExitFailed;
    show_logs = true;
  }
  if (coordinator && !coordinator->error().empty())
    spdlog::error("render --workers: the coordinator stopped: {}", coordinator->error());
  std::vector<std::string> killed;
  if (rc == 0) {
    // The job is done and its result saved: the workers hold nothing, so a clean stop would only make the user wait.
    worker::kill_children(workers);
  } else {
    // Told twice, so that they drop their tile at once.
    killed = worker::stop_children(workers, 5s, 2);
  }
  for (const auto& name : killed) spdlog::warn("{} did not stop within 5 s and was killed", name);
  coordinator.reset();  // requests in flight finish; its threads are joined
  if (show_logs) {
    if (!dir.empty())
      spdlog::error("coordinator, last lines of {}:\n{}", (dir / "serve.log").string(),
                    worker::tail_of_file(dir / "serve.log", 8));
    for (const auto& c : workers)
      spdlog::error("{} ({}), last lines of {}:\n{}", c.name, worker::describe_exit(c), c.log.string(),
                    worker::tail_of_file(c.log, 8));
    if (!dir.empty()) spdlog::error("logs kept in {}", dir.string());
  } else if (!dir.empty()) {
    farm_log.reset();  // its file closed before the folder goes
    std::error_code ec;
    remove_tree(dir, ec);  // its entries in parallel: one by one, a disk that waits per entry took 70 ms
  }
  return rc;
}

int render_farm_sequence(const RenderArgs& a, const std::vector<FrameFile>& frames) {
  if (a.skip_existing || !a.resume.empty()) {
    spdlog::error("--skip-existing and --resume render frames in this process: drop --workers, or give --frames "
                  "for the frames still missing");
    return kExitRefused;
  }
  const fs::path first = frame_output(a.output, frames.front().number, frames.size());
  if (!output_writable(first) ||
      (!a.preview.empty() && !output_writable(frame_output(a.preview, frames.front().number, frames.size()), "preview")))
    return kExitRefused;
  std::vector<client::FrameScene> scenes;
  scenes.reserve(frames.size());
  for (const FrameFile& f : frames) scenes.push_back({f.number, f.scene});
  return run_render_farm(a, scenes);
}

}  // namespace tessera::cli
