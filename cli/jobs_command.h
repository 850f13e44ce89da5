// `tessera jobs`: look at and control a coordinator's jobs (ls, show, tiles, requeue, pause, resume, priority, spp,
// retry, cancel, rm), and wait for one and fetch its result (wait).
#pragma once

#include "cli/coordinator_access.h"
#include "client/http_client.h"

#include <CLI/CLI.hpp>

#include <optional>
#include <string>
#include <vector>

namespace tessera::cli {

/// Options of `tessera jobs`.
struct JobsArgs {
  std::string action;       ///< ls, show, tiles, requeue, pause, resume, priority, spp, retry, frames, cancel, rm or wait.
  std::string job;          ///< The job id (all but ls).
  std::optional<int> priority;  ///< The new priority (priority), samples per pixel (spp) or tile number (requeue).
  bool tiles = false;       ///< show: print the tile table too.
  std::string frames;       ///< retry: only these frames of a sequence (a range, cli/frame_list.h).
  bool purge = false;       ///< rm: delete an ended job entirely (else rm cancels).
  std::vector<std::string> states;  ///< ls: only jobs in these states.
  size_t limit = 0;         ///< ls: at most this many (0: all).
  std::string after;        ///< ls: the page after this cursor or job id.
  bool mine = false;        ///< ls: only the caller's jobs.
  std::string owner;        ///< ls: only this user's jobs.
  std::string output;       ///< wait: where to save the finished job's EXR (empty: not saved).
  bool quiet = false;       ///< wait: no progress bar.
  CoordinatorAccess access;     ///< Coordinator URL, token and TLS files.
};

/// Registers the subcommand's options on `app`.
CLI::App* add_jobs_command(CLI::App& app, JobsArgs& args);

/// Runs it; returns the process exit code: 0 done, 2 refused by the coordinator (unknown id, wrong state) or an output
/// that cannot be written, 1 other errors (coordinator unreachable; wait: the job failed or was cancelled), 130 wait
/// stopped by Ctrl-C or SIGTERM (the job left as it is).
int run_jobs(const JobsArgs& args);

}  // namespace tessera::cli
