#include "cli/render_farm.h"

#include "cli/exit_status.h"
#include "cli/frame_list.h"
#include "cli/output_check.h"
#include "cli/interrupt_guard.h"
#include "cli/submit_command.h"
#include "core/image/exr_multipart.h"
#include "core/image/image.h"
#include "core/render/layer_film.h"
#include "server/auth.h"
#include "server/coordinator_store.h"
#include "server/storage.h"
#include "core/util/file_io.h"
#include "core/util/remove_tree.h"
#include "core/scene/scene_loader.h"
#include "worker/arena_pinning.h"
#include "worker/asset_cache.h"
#include "worker/child_process.h"
#include "client/http_client.h"

#include <spdlog/spdlog.h>

#include <arpa/inet.h>
#include <fcntl.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <unistd.h>

#include <cerrno>
#include <cstdlib>
#include <cstring>
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
  std::vector<worker::ChildProcess> children;
  fs::path dir;
  int rc = kExitFailed;
  bool show_logs = false;
  try {
    dir = make_temp_dir();
    const std::string self = fs::read_symlink("/proc/self/exe").string();
    // Fresh tokens per render: other users of this machine cannot submit to or pose as workers of this farm.
    const std::string client_token = write_token_file(dir / "client.token");
    write_token_file(dir / "worker.token");
    // The private coordinator's folder is thrown away with this command, and a crash of the coordinator fails the
    // render anyway: it keeps its jobs in memory and never waits for the disk. Its one job is refused only by a full
    // disk, not by a floor of free space.
    const auto [listen_fd, port] = listen_on_loopback();
    const std::vector<std::string> limits = asset_limit_args(a.asset_limits);  // the coordinator's and the workers'
    try {
      std::vector<std::string> argv{self, "serve", "--listen", "fd:" + std::to_string(listen_fd), "--data",
                                    (dir / "data").string(), "--client-token-file", (dir / "client.token").string(),
                                    "--worker-token-file", (dir / "worker.token").string(), "--durability", "none", "--min-free-disk", "0"};
      argv.insert(argv.end(), limits.begin(), limits.end());
      children.push_back(worker::spawn_child(argv, "coordinator", dir / "serve.log", listen_fd));
    } catch (...) {
      ::close(listen_fd);
      throw;
    }
    ::close(listen_fd);  // the coordinator's now: should it die, connecting fails instead of waiting
    const std::string url = "http://127.0.0.1:" + std::to_string(port);
    client::SubmitOptions o = shared_job_options(a);
    o.frames = frames;
    o.frame_order = protocol::frame_order_from_string(a.frame_order);
    o.tile_size = a.farm_tile;
    o.resumable = a.resumable;  // the result then carries the state channels, as `render --resumable` writes them
    // While the coordinator starts: the scene's assets are hashed and put in the workers' cache, where they would
    // otherwise fetch them one by one from the coordinator, and linked into the coordinator's blob folder, so that
    // the submission finds them stored instead of uploading each one.
    std::optional<client::SceneFiles> files;
    try {
      files = client::read_scene_files(o);
      worker::AssetCache cache(dir / "cache");
      const fs::path blobs = server::blobs_dir(dir / "data");
      const auto store = [&](const client::LocalAsset& asset) {
        const fs::path verified = cache.get(asset.sha256, [&](const std::string&) { return read_file_bytes(asset.file); });
        // A whole file appears at once (no temp file for the starting coordinator to clear); should it fail, the
        // submission uploads the asset.
        const fs::path stored = server::blob_file(blobs, asset.sha256);
        std::error_code ec;
        fs::create_directories(stored.parent_path(), ec);
        if (!ec) fs::create_hard_link(verified, stored, ec);
        if (ec && ec != std::errc::file_exists)
          spdlog::debug("{} goes to the coordinator by upload: {}", asset.path, ec.message());
      };
      for (const client::LocalAsset& asset : files->assets) store(asset);
      for (const client::FrameFiles& frame : files->frames)
        for (const client::LocalAsset& asset : frame.assets) store(asset);
    } catch (const SceneError& e) {
      spdlog::error("{}", e.what());
      rc = kExitRefused;
    } catch (const client::SubmitError& e) {
      spdlog::error("{}", e.what());
      rc = kExitRefused;
    }
    if (rc == kExitRefused) throw Refused();
    // The workers load the job's scene from their cache while the coordinator starts and checks the submission.
    // (A sequence's frames are loaded as they are leased.)
    const fs::path expected_job = dir / "job.json";
    if (frames.empty())
      write_file_atomic(expected_job, nlohmann::json(client::job_submission(o, *files)).dump(), Flush::none);
    client::HttpClient http(client::parse_http_url(url));
    http.set_bearer_token(client_token);
    // The workers start while the coordinator starts and the job is submitted: until it is in they ask for work every
    // few milliseconds (a private farm's coordinator has nothing else to do), so the first lease follows the job's
    // acceptance at once.
    const unsigned cores = std::max(1u, std::thread::hardware_concurrency());
    const int threads = a.threads > 0 ? a.threads : std::max(1, int(cores) / a.workers);
    // When the workers' threads fit the CPUs this command may use, each thread gets its own.
    const std::vector<int> cpus = worker::allowed_cpus();
    const bool pin = size_t(a.workers) * size_t(threads) <= cpus.size();
    for (int i = 0; i < a.workers; ++i) {
      std::vector<std::string> argv{self, "worker", "--coordinator", url, "--threads", std::to_string(threads),
                                    "--cache", (dir / "cache").string(), "--name", "local-" + std::to_string(i),
                                    "--token-file", (dir / "worker.token").string(), "--max-idle-wait-ms",
                                    std::to_string(kPrivateIdleWaitMs)};
      if (frames.empty()) argv.insert(argv.end(), {"--preload", expected_job.string()});
      argv.insert(argv.end(), limits.begin(), limits.end());
      if (pin) {
        std::string list;
        for (int t = 0; t < threads; ++t) list += (t ? "," : "") + std::to_string(cpus[size_t(i * threads + t)]);
        argv.insert(argv.end(), {"--cpus", list});
      }
      children.push_back(worker::spawn_child(argv, "worker " + std::to_string(i), dir / ("worker-" + std::to_string(i) + ".log")));
    }
    if (!a.quiet)
      std::fprintf(stderr, "coordinator on %s, %d worker(s) with %d thread(s) each\n", url.c_str(), a.workers, threads);
    rc = submit_and_wait(
        http, o, a.output, a.quiet,
        [&] {
          if (InterruptGuard::interrupted()) return true;
          // Every worker gone means no progress is possible.
          bool all_workers_gone = children.size() > 1;
          for (size_t i = 1; i < children.size(); ++i) all_workers_gone &= worker::child_exited(children[i]);
          return all_workers_gone || worker::child_exited(children[0]);
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
  std::vector<worker::ChildProcess> workers(children.begin() + std::min<size_t>(1, children.size()), children.end());
  std::vector<worker::ChildProcess> serve(children.begin(), children.begin() + std::min<size_t>(1, children.size()));
  std::vector<std::string> killed;
  if (rc == 0) {
    // The job is done and its result saved: the workers hold nothing and the coordinator's folder is thrown away, so
    // a clean shutdown (the coordinator's last checkpoint, joining every thread) would only make the user wait, about
    // 10 ms. The coordinator is built to survive SIGKILL at any moment anyway.
    worker::kill_children(children);
    workers.assign(children.begin() + std::min<size_t>(1, children.size()), children.end());
    serve.assign(children.begin(), children.begin() + std::min<size_t>(1, children.size()));
  } else {
    // Workers first (told twice, so they drop their tile at once), then the coordinator.
    killed = worker::stop_children(workers, 5s, 2);
    const auto killed_serve = worker::stop_children(serve, 5s);
    killed.insert(killed.end(), killed_serve.begin(), killed_serve.end());
  }
  for (const auto& name : killed) spdlog::warn("{} did not stop within 5 s and was killed", name);
  children = serve;
  children.insert(children.end(), workers.begin(), workers.end());
  if (show_logs) {
    for (const auto& c : children)
      spdlog::error("{} ({}), last lines of {}:\n{}", c.name, worker::describe_exit(c), c.log.string(),
                    worker::tail_of_file(c.log, 8));
    if (!dir.empty()) spdlog::error("logs kept in {}", dir.string());
  } else if (!dir.empty()) {
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
