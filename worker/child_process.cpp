#include "worker/child_process.h"

#include <fcntl.h>
#include <signal.h>
#include <sys/prctl.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cerrno>
#include <cstdio>
#include <cstring>
#include <deque>
#include <fstream>
#include <stdexcept>
#include <thread>

namespace tessera::worker {

namespace {

// In a new child, before anything else: its own process group, killed with `parent`, the signal mask and dispositions
// a program expects, stdin from /dev/null, stdout and stderr appended to `log_fd`. Async-signal-safe calls only.
void prepare_child(pid_t parent, int log_fd) {
  ::setpgid(0, 0);
  ::prctl(PR_SET_PDEATHSIG, SIGKILL);
  if (::getppid() != parent) ::_exit(127);  // the parent died before prctl took effect
  // Signals ignored or blocked by the parent stay so in the child: restore the defaults it expects.
  sigset_t none;
  sigemptyset(&none);
  ::sigprocmask(SIG_SETMASK, &none, nullptr);
  ::signal(SIGINT, SIG_DFL);
  ::signal(SIGTERM, SIG_DFL);
  ::signal(SIGPIPE, SIG_DFL);
  const int null_fd = ::open("/dev/null", O_RDONLY);
  if (null_fd >= 0) ::dup2(null_fd, STDIN_FILENO);
  ::dup2(log_fd, STDOUT_FILENO);
  ::dup2(log_fd, STDERR_FILENO);
}

// The log file a child's stdout and stderr are appended to (close-on-exec); throws naming the child.
int open_log(const std::filesystem::path& log, const std::string& name) {
  const int log_fd = ::open(log.c_str(), O_WRONLY | O_CREAT | O_APPEND | O_CLOEXEC, 0644);
  if (log_fd < 0) throw std::runtime_error("cannot start " + name + ": cannot open " + log.string() + ": " + std::strerror(errno));
  return log_fd;
}

pid_t fork_or_throw(int log_fd, const std::string& name) {
  const pid_t pid = ::fork();
  if (pid < 0) {
    const int err = errno;
    ::close(log_fd);
    throw std::runtime_error("cannot start " + name + ": fork: " + std::strerror(err));
  }
  return pid;
}

ChildProcess started(pid_t pid, int log_fd, const std::string& name, const std::filesystem::path& log) {
  ::close(log_fd);
  ChildProcess c;
  c.pid = pid;
  c.name = name;
  c.log = log;
  return c;
}

}  // namespace

ChildProcess spawn_child(const std::vector<std::string>& argv, const std::string& name, const std::filesystem::path& log,
                         int pass_fd) {
  if (argv.empty()) throw std::runtime_error("cannot start " + name + ": empty command line");
  // Everything the child needs is prepared before fork: after it, only async-signal-safe calls.
  std::vector<char*> args;
  for (const auto& a : argv) args.push_back(const_cast<char*>(a.c_str()));
  args.push_back(nullptr);
  const int log_fd = open_log(log, name);
  const pid_t parent = ::getpid();
  const pid_t pid = fork_or_throw(log_fd, name);
  if (pid == 0) {
    prepare_child(parent, log_fd);
    if (pass_fd >= 0) ::fcntl(pass_fd, F_SETFD, 0);
    ::execv(args[0], args.data());
    ::_exit(127);
  }
  return started(pid, log_fd, name, log);
}

bool single_threaded() {
  std::error_code ec;
  size_t tasks = 0;
  for (auto it = std::filesystem::directory_iterator("/proc/self/task", ec); !ec && it != std::filesystem::directory_iterator();
       it.increment(ec))
    ++tasks;
  return !ec && tasks == 1;
}

ChildProcess fork_child(const std::function<int()>& body, const std::string& name, const std::filesystem::path& log,
                        int keep_fd, const char* title) {
  if (!single_threaded())
    throw std::logic_error("cannot start " + name + " without exec: this process runs other threads");
  const int log_fd = open_log(log, name);
  const pid_t parent = ::getpid();
  std::fflush(nullptr);  // nothing buffered here is written twice
  const pid_t pid = fork_or_throw(log_fd, name);
  if (pid == 0) {
    prepare_child(parent, log_fd);
    // What exec would have closed (every descriptor here is close-on-exec) is closed, `keep_fd` kept.
    if (keep_fd > STDERR_FILENO) {
      ::close_range(STDERR_FILENO + 1, unsigned(keep_fd) - 1, 0);
      ::close_range(unsigned(keep_fd) + 1, ~0U, 0);
    } else {
      ::close_range(STDERR_FILENO + 1, ~0U, 0);
    }
    if (title) ::prctl(PR_SET_NAME, title);
    int rc = 1;
    try {
      rc = body();
    } catch (...) {
    }
    std::fflush(nullptr);
    ::_exit(rc);  // never into the parent's code, its destructors or exit handlers
  }
  return started(pid, log_fd, name, log);
}

bool child_exited(ChildProcess& c) {
  if (c.reaped) return true;
  if (c.pid <= 0) return true;
  int status = 0;
  const pid_t r = ::waitpid(c.pid, &status, WNOHANG);
  if (r == c.pid || (r < 0 && errno == ECHILD)) {
    c.reaped = true;
    c.exit_status = r == c.pid ? status : -1;
    return true;
  }
  return false;
}

namespace {

// Waits for a child that was sent SIGKILL and records its status (-1 when it cannot be had).
void reap_killed(ChildProcess& c) {
  if (c.reaped || c.pid <= 0) return;
  int status = 0;
  pid_t r;
  while ((r = ::waitpid(c.pid, &status, 0)) < 0 && errno == EINTR) {
  }
  c.reaped = true;
  c.exit_status = r == c.pid ? status : -1;
}

}  // namespace

std::vector<std::string> stop_children(std::vector<ChildProcess>& children, std::chrono::milliseconds grace,
                                       int terms) {
  for (int i = 0; i < terms; ++i) {
    if (i > 0) std::this_thread::sleep_for(std::chrono::milliseconds(20));
    for (auto& c : children)
      if (!child_exited(c)) ::kill(c.pid, SIGTERM);
  }
  const auto deadline = std::chrono::steady_clock::now() + grace;
  while (std::chrono::steady_clock::now() < deadline) {
    bool all = true;
    for (auto& c : children) all &= child_exited(c);
    if (all) return {};
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
  }
  std::vector<std::string> killed;
  for (auto& c : children) {
    if (child_exited(c)) continue;
    ::kill(c.pid, SIGKILL);
    reap_killed(c);
    killed.push_back(c.name);
  }
  return killed;
}

void kill_children(std::vector<ChildProcess>& children) {
  for (auto& c : children)
    if (!child_exited(c)) ::kill(c.pid, SIGKILL);
  for (auto& c : children) reap_killed(c);
}

std::string describe_exit(const ChildProcess& c) {
  if (!c.reaped) return "still running";
  if (c.exit_status < 0) return "exit status unknown";
  if (WIFEXITED(c.exit_status)) return "exited with status " + std::to_string(WEXITSTATUS(c.exit_status));
  if (WIFSIGNALED(c.exit_status)) return "killed by signal " + std::to_string(WTERMSIG(c.exit_status));
  return "stopped";
}

std::string tail_of_file(const std::filesystem::path& path, int max_lines) {
  std::ifstream in(path);
  std::deque<std::string> lines;
  for (std::string line; std::getline(in, line);) {
    lines.push_back(line);
    if (int(lines.size()) > max_lines) lines.pop_front();
  }
  std::string out;
  for (const auto& l : lines) out += "    " + l + "\n";
  return out;
}

}  // namespace tessera::worker
