// Starting and stopping helper processes: the workers of `tessera render --workers` (forked copies, or `tessera worker`
// started with exec), and the coordinators and workers that benches and tests start.
#pragma once

#include <chrono>
#include <filesystem>
#include <functional>
#include <string>
#include <sys/types.h>
#include <vector>

namespace tessera::worker {

/// A child process started by spawn_child or fork_child; stopping is explicit (stop_children), never in a destructor.
struct ChildProcess {
  pid_t pid = -1;              ///< Process id (-1: not running).
  std::string name;            ///< For messages, e.g. "worker 2".
  std::filesystem::path log;   ///< Where its stdout and stderr go.
  int exit_status = -1;        ///< waitpid status once reaped.
  bool reaped = false;         ///< True once waited for.
};

/// Starts argv[0] with argv (fork + exec), stdout and stderr appended to log, in its own process group (so a
/// terminal's Ctrl-C reaches only the parent, which stops it in order) and killed if the parent dies; `pass_fd` (when
/// not -1) stays open in the child under its number, other close-on-exec descriptors do not. Throws
/// std::runtime_error naming the program when it cannot start.
ChildProcess spawn_child(const std::vector<std::string>& argv, const std::string& name, const std::filesystem::path& log,
                         int pass_fd = -1);

/// True when this process runs one thread (this one): fork_child may then run code in the child.
bool single_threaded();

/// Starts a child that runs `body` in a copy of this process (fork without exec: nothing to load and link), set up
/// as spawn_child sets up its children, with every descriptor but 0-2 and `keep_fd` (when not -1) closed and its
/// name (comm, as `ps` and `top` show it) `title` when given; the child exits with body's result (1 when it throws),
/// without running this process's destructors or exit handlers. Only from a single-threaded process (a child of a
/// threaded one would inherit locks held by threads it does not have): throws std::logic_error otherwise, and
/// std::runtime_error when the child cannot start.
ChildProcess fork_child(const std::function<int()>& body, const std::string& name, const std::filesystem::path& log,
                        int keep_fd = -1, const char* title = nullptr);

/// True (and status recorded) when the child has exited; never blocks.
bool child_exited(ChildProcess& child);

/// Sends SIGTERM (`terms` times, 20 ms apart: a worker told twice hands its tile back at once) to every running
/// child, waits up to `grace` for them to exit, then SIGKILLs and reaps the rest. Returns the names of children that
/// had to be killed.
std::vector<std::string> stop_children(std::vector<ChildProcess>& children, std::chrono::milliseconds grace,
                                       int terms = 1);

/// SIGKILLs every running child and reaps it: for children that hold nothing worth a clean shutdown.
void kill_children(std::vector<ChildProcess>& children);

/// "exited with status N" or "killed by signal N" for a reaped child.
std::string describe_exit(const ChildProcess& child);

/// The last max_lines lines of a text file ("" when unreadable), for error reports.
std::string tail_of_file(const std::filesystem::path& path, int max_lines);

}  // namespace tessera::worker
