#include "server/steps/movie_encoder.h"

#include "core/image/image.h"
#include "core/util/file_io.h"

#include <fcntl.h>
#include <poll.h>
#include <signal.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cerrno>
#include <chrono>
#include <cstring>
#include <deque>
#include <fstream>
#include <string>

namespace fs = std::filesystem;

namespace tessera::server {

namespace {

// The lines of ffmpeg's log a failure quotes, and their bytes at most.
constexpr size_t kLogTailLines = 20;
constexpr size_t kLogTailBytes = 4000;

std::string log_tail(const fs::path& log) {
  std::ifstream in(log);
  std::deque<std::string> lines;
  for (std::string line; std::getline(in, line);) {
    if (line.empty()) continue;
    lines.push_back(std::move(line));
    if (lines.size() > kLogTailLines) lines.pop_front();
  }
  std::string out;
  for (const std::string& l : lines) out += l + "\n";
  if (out.size() > kLogTailBytes) out = "..." + out.substr(out.size() - kLogTailBytes);
  while (!out.empty() && out.back() == '\n') out.pop_back();
  return out.empty() ? "(its log is empty)" : out;
}

std::string describe_status(int status) {
  if (WIFEXITED(status)) return "exited with status " + std::to_string(WEXITSTATUS(status));
  if (WIFSIGNALED(status)) return "was killed by signal " + std::to_string(WTERMSIG(status));
  return "ended abnormally";
}

// A descriptor closed when it goes.
struct Fd {
  int fd = -1;
  ~Fd() { reset(); }
  void reset() {
    if (fd >= 0) ::close(fd);
    fd = -1;
  }
};

// How often a wait on ffmpeg (for room in the pipe, or for its exit) looks whether the encoder is to stop.
constexpr int kStopCheckMs = 50;

// When ffmpeg last made progress (read from the pipe, or was fed its last frame); throws once it made none for longer
// than the job allows.
struct Progress {
  using Clock = std::chrono::steady_clock;
  double limit_seconds;
  Clock::time_point last = Clock::now();
  void made() { last = Clock::now(); }
  void check(const char* waiting_for) const {
    if (std::chrono::duration<double>(Clock::now() - last).count() > limit_seconds)
      throw std::runtime_error("ffmpeg " + std::string(waiting_for) + " for " + std::to_string(int(limit_seconds)) +
                               " s and was killed");
  }
};

// The child: killed and reaped unless it was waited for.
struct Child {
  pid_t pid = -1;
  ~Child() {
    if (pid > 0) {
      ::kill(pid, SIGKILL);
      int status = 0;
      while (::waitpid(pid, &status, 0) < 0 && errno == EINTR) {
      }
    }
  }
  // Its exit status, once it exited; throws EncodeInterrupted (the destructor then kills it) when `stopping` turns true
  // first, so that an ffmpeg that hangs does not hold the coordinator's stop.
  // Throws std::runtime_error when it has not exited `progress`'s limit after its input ended.
  int wait(const std::function<bool()>& stopping, const Progress& progress) {
    while (true) {
      int status = 0;
      const pid_t r = ::waitpid(pid, &status, WNOHANG);
      if (r == pid) {
        pid = -1;
        return status;
      }
      if (r < 0 && errno != EINTR) throw std::runtime_error(std::string("cannot wait for ffmpeg: ") + std::strerror(errno));
      if (stopping()) throw EncodeInterrupted("stopped while ffmpeg finished the movie");
      progress.check("did not finish the movie");
      ::poll(nullptr, 0, kStopCheckMs);
    }
  }
};

// SIGPIPE blocked in this thread while it writes to ffmpeg (a write after ffmpeg exited fails with EPIPE instead of
// killing the coordinator); one left pending is taken before the thread's mask is put back.
struct SigpipeBlocked {
  sigset_t pipe_set{}, old{};
  SigpipeBlocked() {
    sigemptyset(&pipe_set);
    sigaddset(&pipe_set, SIGPIPE);
    pthread_sigmask(SIG_BLOCK, &pipe_set, &old);
  }
  ~SigpipeBlocked() {
    const timespec zero{0, 0};
    while (sigtimedwait(&pipe_set, nullptr, &zero) > 0) {
    }
    pthread_sigmask(SIG_SETMASK, &old, nullptr);
  }
};

// Writes all of `bytes` to the (non-blocking) pipe; false when ffmpeg stopped reading (EPIPE). Throws
// EncodeInterrupted when `stopping` turns true while the pipe is full, std::runtime_error when ffmpeg read nothing for
// `progress`'s limit.
bool write_all(int fd, const uint8_t* bytes, size_t n, const std::function<bool()>& stopping, Progress& progress) {
  while (n > 0) {
    const ssize_t w = ::write(fd, bytes, n);
    if (w < 0 && errno == EINTR) continue;
    if (w < 0 && errno == EPIPE) return false;
    if (w < 0 && errno == EAGAIN) {
      if (stopping()) throw EncodeInterrupted("stopped while ffmpeg read a frame");
      progress.check("read nothing");
      pollfd p{fd, POLLOUT, 0};
      ::poll(&p, 1, kStopCheckMs);
      continue;
    }
    if (w < 0) throw std::runtime_error(std::string("cannot feed ffmpeg: ") + std::strerror(errno));
    progress.made();
    bytes += w;
    n -= size_t(w);
  }
  return true;
}

// A file removed when it goes, unless kept.
struct Partial {
  fs::path path;
  bool keep = false;
  ~Partial() {
    std::error_code ec;
    if (!keep) fs::remove(path, ec);
  }
};

}  // namespace

void encode_movie(const MovieJob& job, const std::function<bool()>& stopping) {
  if (job.frames.empty()) throw std::runtime_error("a movie needs at least one frame");
  // The first frame fixes the size every frame must have.
  Image first = read_exr(job.frames.front()).pixels;
  const std::string size = std::to_string(first.width) + "x" + std::to_string(first.height);
  Partial written{job.output.parent_path() / ("." + job.output.filename().string() + ".partial")};
  const fs::path& partial = written.path;
  std::error_code ec;
  fs::remove(partial, ec);
  // The argument vector is fixed but for the numbers and the coordinator's own file names.
  const std::string fps = std::to_string(job.fps);
  const std::vector<std::string> args = {
      job.ffmpeg.string(), "-hide_banner", "-nostats", "-loglevel", "error",
      "-f", "rawvideo", "-pixel_format", "rgb24", "-video_size", size, "-framerate", fps, "-i", "pipe:0",
      "-vf", "pad=ceil(iw/2)*2:ceil(ih/2)*2", "-c:v", "libx264", "-pix_fmt", "yuv420p",
      "-movflags", "+faststart", "-f", "mp4", "-y", partial.string()};
  std::vector<char*> argv;
  for (const std::string& a : args) argv.push_back(const_cast<char*>(a.c_str()));
  argv.push_back(nullptr);
  char* no_environment[] = {nullptr};

  int pipe_fds[2];
  if (::pipe2(pipe_fds, O_CLOEXEC) != 0)
    throw std::runtime_error(std::string("cannot make a pipe to ffmpeg: ") + std::strerror(errno));
  Fd read_end{pipe_fds[0]}, write_end{pipe_fds[1]};
  Fd log{::open(job.log.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0600)};
  if (log.fd < 0) throw std::runtime_error("cannot open " + job.log.string() + ": " + std::strerror(errno));

  posix_spawn_file_actions_t actions;
  posix_spawn_file_actions_init(&actions);
  posix_spawn_file_actions_adddup2(&actions, read_end.fd, STDIN_FILENO);
  posix_spawn_file_actions_adddup2(&actions, log.fd, STDOUT_FILENO);
  posix_spawn_file_actions_adddup2(&actions, log.fd, STDERR_FILENO);
  posix_spawnattr_t attr;
  posix_spawnattr_init(&attr);
  sigset_t none, defaults;
  sigemptyset(&none);
  sigfillset(&defaults);
  posix_spawnattr_setsigmask(&attr, &none);        // the coordinator's helper threads block every signal
  posix_spawnattr_setsigdefault(&attr, &defaults);  // and what it ignores is not ffmpeg's business
  posix_spawnattr_setpgroup(&attr, 0);             // a terminal's Ctrl-C is the coordinator's to handle
  posix_spawnattr_setflags(&attr, POSIX_SPAWN_SETSIGMASK | POSIX_SPAWN_SETSIGDEF | POSIX_SPAWN_SETPGROUP);
  Child child;
  const int spawned = ::posix_spawn(&child.pid, argv[0], &actions, &attr, argv.data(), no_environment);
  posix_spawn_file_actions_destroy(&actions);
  posix_spawnattr_destroy(&attr);
  if (spawned != 0) {
    child.pid = -1;
    throw std::runtime_error("cannot run " + job.ffmpeg.string() + ": " + std::strerror(spawned));
  }
  read_end.reset();
  log.reset();
  if (::fcntl(write_end.fd, F_SETFL, O_NONBLOCK) != 0)
    throw std::runtime_error(std::string("cannot feed ffmpeg: ") + std::strerror(errno));

  bool fed = true;
  Progress progress{job.stall_seconds};
  {
    SigpipeBlocked quiet;
    for (size_t i = 0; i < job.frames.size() && fed; ++i) {
      if (stopping()) throw EncodeInterrupted("stopped before frame " + std::to_string(i + 1) + " was encoded");
      Image img = i == 0 ? std::move(first) : read_exr(job.frames[i]).pixels;
      const std::string this_size = std::to_string(img.width) + "x" + std::to_string(img.height);
      if (this_size != size)
        throw std::runtime_error("a movie's frames must have one size: " + job.frames[i].string() + " is " + this_size +
                                 ", the first frame " + size);
      const std::vector<uint8_t> rgb = srgb8_pixels(img);
      fed = write_all(write_end.fd, rgb.data(), rgb.size(), stopping, progress);
    }
  }
  write_end.reset();  // end of input: ffmpeg finishes the file
  progress.made();
  int status = 0;
  try {
    status = child.wait(stopping, progress);
  } catch (const EncodeInterrupted&) {
    throw;
  } catch (const std::runtime_error& e) {
    throw std::runtime_error(std::string(e.what()) + "; the end of its log:\n" + log_tail(job.log));
  }
  if (!fed || !WIFEXITED(status) || WEXITSTATUS(status) != 0)
    throw std::runtime_error("ffmpeg " + (fed ? describe_status(status)
                                              : describe_status(status) + " before it read every frame") +
                             "; the end of its log:\n" + log_tail(job.log));
  if (!fs::is_regular_file(partial, ec) || fs::file_size(partial, ec) == 0)
    throw std::runtime_error("ffmpeg exited with status 0 but wrote no movie; the end of its log:\n" +
                             log_tail(job.log));
  move_file_atomic(partial, job.output);  // flushed, renamed, the rename flushed
  written.keep = true;
}

}  // namespace tessera::server
