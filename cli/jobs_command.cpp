#include "cli/jobs_command.h"

#include "cli/exit_status.h"
#include "cli/frame_list.h"
#include "cli/interrupt_guard.h"
#include "cli/output_check.h"
#include "cli/progress_bar.h"
#include "cli/submit_command.h"
#include "client/http_client.h"
#include "client/job_client.h"

#include <nlohmann/json.hpp>
#include <spdlog/spdlog.h>

#include <chrono>
#include <cstdio>
#include <filesystem>
#include <sstream>

namespace tessera::cli {

namespace {

// Under a job with dependencies: what it waits for ("after j-1, j-2 (per frame)") and why it is held.
void print_dependencies(const protocol::JobStatus& j) {
  const protocol::Pipeline& p = j.params.pipeline;
  if (p.after.empty() && j.dependents.empty()) return;
  std::string line;
  for (const std::string& id : p.after) line += (line.empty() ? "after " : ", ") + id;
  if (p.per_frame) line += " (per frame)";
  if (!j.dependents.empty()) {
    line += line.empty() ? "" : "; ";
    for (size_t i = 0; i < j.dependents.size(); ++i) line += (i ? ", " : "then ") + j.dependents[i];
  }
  if (j.reason) line += ": " + *j.reason;
  std::printf("%-20s   %s\n", "", line.c_str());
}

// One line per job: id, state, owner, priority, tiles done/total, render time (first lease to the end, or to now)
// and the rays per second over it, name (and what it waits for, if no worker may take it).
void print_table(const std::vector<protocol::JobStatus>& jobs) {
  std::printf("%-20s %-10s %-12s %8s %13s %8s %8s  %s\n", "ID", "STATE", "OWNER", "PRIORITY", "TILES", "TIME",
              "MRAYS/S", "NAME");
  for (const protocol::JobStatus& j : jobs) {
    const std::string tiles = std::to_string(j.tiles.done) + "/" + std::to_string(j.tiles.total);
    const std::string time = j.render_seconds > 0 ? format_duration(j.render_seconds) : "-";
    // A sequence's frames follow its name: "[3/24 frames, 1 failed]".
    std::string name = j.params.name;
    if (j.frames)
      name += " [" + std::to_string(j.frames->done) + "/" + std::to_string(j.frames->total) + " frames" +
              (j.frames->failed ? ", " + std::to_string(j.frames->failed) + " failed" : "") + "]";
    if (j.waiting_for) name += " (waiting for " + *j.waiting_for + ")";
    const std::string owner = j.params.owner.empty() ? "-" : j.params.owner;
    std::printf("%-20s %-10s %-12s %8d %13s %8s %8s  %s\n", j.id.c_str(), protocol::to_string(j.state), owner.c_str(),
                j.params.priority, tiles.c_str(), time.c_str(), format_mrays(j.rays, j.render_seconds).c_str(),
                name.c_str());
    print_dependencies(j);
  }
}

// One line per step of a done job: its name, state and files (or its log when it failed); with `dir`, the done steps'
// files are saved in that folder under their own names. kExitFailed when a step failed, kExitOk otherwise.
int print_outputs(client::HttpClient& http, const std::string& id, const std::string& dir) {
  const protocol::JobStatus s = client::get_job(http, id);
  if (s.params.pipeline.then.empty()) throw client::SubmitError("job " + id + " has no steps (submit --then names them)");
  if (s.state != protocol::JobState::done)
    throw client::SubmitError("job " + id + " is " + protocol::to_string(s.state) + ": its steps run once it is done");
  bool failed = false;
  for (const protocol::StepOutput& o : s.outputs) {
    std::string files;
    for (const std::string& f : o.files) files += (files.empty() ? "" : " ") + f;
    std::printf("%-14s %-8s %s\n", protocol::to_string(o.step), o.state.c_str(), files.c_str());
    if (o.state == "failed") {
      failed = true;
      std::istringstream log(o.log);
      for (std::string line; std::getline(log, line);) std::printf("  | %s\n", line.c_str());
    }
    if (dir.empty() || o.state != "done") continue;
    for (const std::string& f : o.files) {
      // The names are the coordinator's: one that is not a plain file name is not followed out of the folder.
      if (f.empty() || f == "." || f == ".." || f.find('/') != std::string::npos)
        throw std::runtime_error("job " + id + " lists an output named '" + f + "', which is not a file name");
      std::filesystem::create_directories(dir);
      const std::filesystem::path to = std::filesystem::path(dir) / f;
      const uint64_t bytes = client::download_output(http, id, f, to);
      std::printf("  saved %s (%llu bytes)\n", to.string().c_str(), static_cast<unsigned long long>(bytes));
    }
  }
  return failed ? kExitFailed : kExitOk;
}

// One line per frame of a sequence: number, its job, state, tiles done/total, render time, error.
void print_frames(client::HttpClient& http, const std::string& id) {
  std::printf("%8s %-26s %-10s %13s %8s  %s\n", "FRAME", "JOB", "STATE", "TILES", "TIME", "ERROR");
  protocol::FrameListQuery q;
  q.limit = 1000;
  while (true) {
    const protocol::FrameList page = client::list_frames(http, id, q);
    for (const protocol::JobStatus& f : page.frames) {
      const std::string tiles = std::to_string(f.tiles.done) + "/" + std::to_string(f.tiles.total);
      const std::string time = f.render_seconds > 0 ? format_duration(f.render_seconds) : "-";
      std::printf("%8lld %-26s %-10s %13s %8s  %s\n", static_cast<long long>(f.frame.value_or(0)), f.id.c_str(),
                  protocol::to_string(f.state), tiles.c_str(), time.c_str(), f.error.value_or("").c_str());
    }
    if (!page.next) break;
    q.after = page.next;
  }
}

// "id (name)", or the id when the name is unknown, or "-".
std::string worker_text(const std::optional<std::string>& id, const std::optional<std::string>& name) {
  if (!id) return "-";
  return *id + (name && !name->empty() ? " (" + *name + ")" : "");
}

// One line per tile (index, state, its worker: the lease holder's, or for a done tile the one that rendered it,
// attempts, render seconds, rays, failing workers), then each failure with the log lines its worker sent, then each
// done tile with the log lines sent with its upload, and how many done tiles' logs were not kept.
void print_tiles(const protocol::TileList& list) {
  std::printf("%6s %-8s %-24s %8s %9s %14s %8s\n", "TILE", "STATE", "WORKER", "ATTEMPTS", "SECONDS", "RAYS", "FAILURES");
  for (const protocol::TileInfo& t : list.tiles) {
    const std::string worker = t.worker ? worker_text(t.worker, t.worker_name) : worker_text(t.rendered_by, t.rendered_by_name);
    char seconds[32] = "-";
    if (t.render_seconds) std::snprintf(seconds, sizeof seconds, "%.3f", *t.render_seconds);
    std::printf("%6lld %-8s %-24s %8lld %9s %14llu %8zu\n", static_cast<long long>(t.index), t.state.c_str(),
                worker.c_str(), static_cast<long long>(t.attempts), seconds,
                static_cast<unsigned long long>(t.rays), t.failures.size());
  }
  for (const protocol::TileInfo& t : list.tiles)
    for (const protocol::TileFailure& f : t.failures) {
      const std::string who = f.worker + (f.worker_name.empty() ? "" : " (" + f.worker_name + ")");
      std::printf("\ntile %lld failed on %s: %s\n", static_cast<long long>(t.index), who.c_str(), f.error.c_str());
      for (const std::string& line : f.log) std::printf("  | %s\n", line.c_str());
    }
  for (const protocol::TileInfo& t : list.tiles) {
    if (t.log.empty()) continue;
    const std::string who = worker_text(t.rendered_by, t.rendered_by_name);
    std::printf("\ntile %lld rendered by %s:\n", static_cast<long long>(t.index), who.c_str());
    for (const std::string& line : t.log) std::printf("  | %s\n", line.c_str());
  }
  if (list.logs_not_kept > 0)
    std::printf("\n%lld done tiles' logs were not kept: the job's tile logs reached the coordinator's bound "
                "(serve --max-tile-log-bytes)\n",
                static_cast<long long>(list.logs_not_kept));
}

}  // namespace

CLI::App* add_jobs_command(CLI::App& app, JobsArgs& a) {
  auto* c = app.add_subcommand("jobs", "List and control a coordinator's jobs");
  c->add_option("action", a.action, "ls: list; show ID: the job as JSON, with its sampling settings; pause ID: no new leases (running tiles "
                                    "finish); resume ID; tiles ID: one line per tile, then failures and done tiles with "
                                    "their log lines; requeue ID N: render tile N again; priority ID N: lease its tiles in a new order; spp ID M: raise a --resumable job to M samples per pixel, continuing its stored tiles; retry ID: render a failed or cancelled job's missing tiles (a sequence: its failed and cancelled frames, or those of --frames); frames ID: one line per frame of a sequence; outputs ID: each step's state and files (submit --then), with -o DIR saved in that folder; "
                                    "cancel ID; rm ID: cancel it, or with --purge delete an ended job, its tiles and result; "
                                    "wait ID: follow the job until it ends and, with -o, save its result (Ctrl-C stops "
                                    "waiting and leaves the job as it is)")
      ->required()
      ->check(CLI::IsMember({"ls", "show", "tiles", "requeue", "pause", "resume", "priority", "spp", "retry", "frames", "outputs", "cancel", "rm",
                             "wait"}));
  c->add_option("job", a.job, "Job id (all but ls)");
  c->add_option("value", a.priority, "New priority, higher runs first (priority); new samples per pixel (spp); the tile number (requeue)");
  c->add_flag("--tiles", a.tiles, "show: print the tile table after the job");
  c->add_option("--frames", a.frames, "retry: only these frames of a sequence (1-240, 1-240x2, 1,5,10-20)");
  c->add_flag("--purge", a.purge, "rm: delete a done, failed or cancelled job entirely (rows, tile pixels, result)");
  c->add_option("--state", a.states, "ls: only jobs in these states (queued, running, paused, done, failed, cancelled, waiting, blocked)")
      ->delimiter(',');
  c->add_option("--limit", a.limit, "ls: at most this many jobs, newest first")
      ->check(CLI::Range(size_t(1), protocol::kMaxJobListLimit));
  c->add_option("--after", a.after, "ls: the page after this cursor (printed by a listing with --limit) or job id");
  c->add_flag("--mine", a.mine, "ls: only the jobs of the user this credential stands for");
  c->add_option("--owner", a.owner, "ls: only this user's jobs");
  c->add_option("-o,--output", a.output,
                "wait: save the finished job's EXR to this file; outputs: save the steps' files in this folder");
  c->add_flag("-q,--quiet", a.quiet, "wait: no progress bar");
  add_coordinator_access_flags(c, a.access);
  return c;
}

int run_jobs(const JobsArgs& a) {
  if (a.action != "ls" && a.job.empty()) {
    spdlog::error("jobs {} needs a job id", a.action);
    return kExitRefused;
  }
  if (a.action == "priority" && !a.priority) {
    spdlog::error("jobs priority needs a job id and the new priority");
    return kExitRefused;
  }
  if (a.action == "spp" && (!a.priority || *a.priority < 1)) {
    spdlog::error("jobs spp needs a job id and the new samples per pixel (a positive number)");
    return kExitRefused;
  }
  if (a.action == "requeue" && !a.priority) {
    spdlog::error("jobs requeue needs a job id and a tile number");
    return kExitRefused;
  }
  if (!a.frames.empty() && a.action != "retry") {
    spdlog::error("--frames goes with jobs retry");
    return kExitRefused;
  }
  if (!a.frames.empty()) try {
      parse_frame_range(a.frames);
    } catch (const std::invalid_argument& e) {
      spdlog::error("{}", e.what());
      return kExitRefused;
    }
  if ((a.mine || !a.owner.empty()) && a.action != "ls") {
    spdlog::error("--mine and --owner go with jobs ls");
    return kExitRefused;
  }
  if (a.mine && !a.owner.empty()) {
    spdlog::error("give --mine or --owner, not both");
    return kExitRefused;
  }
  if (!a.output.empty() && a.action != "wait" && a.action != "outputs") {
    spdlog::error("-o goes with jobs wait or jobs outputs");
    return kExitRefused;
  }
  // Before waiting: a result that could not be saved would be found out only at the end.
  if (!a.output.empty() && a.action == "wait" && !output_writable(a.output)) return kExitRefused;
  return run_with_coordinator(a.access, "jobs " + a.action, [&](client::HttpClient& http) {
    if (a.action == "wait") {
      client::get_job(http, a.job);  // an unknown id is refused here (exit 2), not after a wait
      InterruptGuard interrupts;
      return follow_job(http, a.job, a.output, a.quiet, [] { return InterruptGuard::interrupted(); }, false,
                        std::chrono::steady_clock::now());
    }
    if (a.action == "ls") {
      protocol::JobListQuery q;
      for (const std::string& s : a.states) {
        try {
          q.states.push_back(protocol::job_state_from_string(s));
        } catch (const std::invalid_argument& e) {
          spdlog::error("--state: {}", e.what());
          return kExitRefused;
        }
      }
      q.limit = a.limit;
      q.after = a.after;
      q.owner = a.mine ? client::whoami(http).user : a.owner;
      const protocol::JobList page = client::list_jobs(http, q);
      print_table(page.jobs);
      if (page.next) std::printf("more: --after %s\n", page.next->c_str());
    } else if (a.action == "rm" && a.purge) {
      const protocol::PurgeAnswer p = client::purge_job(http, a.job);
      std::printf("%s: purged (was %s)\n", p.id.c_str(), protocol::to_string(p.was));
    } else if (a.action == "show") {
      // The job's status, and how it samples (all of its settings, from its spec).
      // A sequence samples as its first frame does (every frame has the submission's settings, its spp its own).
      const protocol::JobStatus status = client::get_job(http, a.job);
      const std::string spec_of = status.frames ? protocol::frame_job_id(a.job, status.frames->first) : a.job;
      nlohmann::json job = status;
      job["sampling"] = client::get_job_spec(http, spec_of).sampling;
      std::printf("%s\n", job.dump(2).c_str());
      if (a.tiles && status.frames) print_frames(http, a.job);
      else if (a.tiles) print_tiles(client::get_job_tiles(http, a.job));
    } else if (a.action == "tiles") {
      print_tiles(client::get_job_tiles(http, a.job));
    } else if (a.action == "requeue") {
      const protocol::TileInfo t = client::requeue_tile(http, a.job, *a.priority);
      std::printf("%s tile %lld: %s again\n", a.job.c_str(), static_cast<long long>(t.index), t.state.c_str());
    } else if (a.action == "pause" || a.action == "resume") {
      const protocol::JobStatus s = a.action == "pause" ? client::pause_job(http, a.job) : client::resume_job(http, a.job);
      std::printf("%s: %s\n", s.id.c_str(), protocol::to_string(s.state));
    } else if (a.action == "priority") {
      const protocol::JobStatus s = client::set_job_priority(http, a.job, *a.priority);
      std::printf("%s: %s, priority %d\n", s.id.c_str(), protocol::to_string(s.state), s.params.priority);
    } else if (a.action == "spp") {
      const protocol::JobStatus s = client::raise_job_spp(http, a.job, uint32_t(*a.priority));
      std::printf("%s: %s at %u spp, %lld of %lld tiles to continue\n", s.id.c_str(), protocol::to_string(s.state),
                  s.params.spp, static_cast<long long>(s.tiles.total - s.tiles.done),
                  static_cast<long long>(s.tiles.total));
    } else if (a.action == "frames") {
      print_frames(http, a.job);
    } else if (a.action == "outputs") {
      return print_outputs(http, a.job, a.output);
    } else if (a.action == "retry") {
      std::vector<int64_t> frames;
      if (!a.frames.empty()) frames = parse_frame_range(a.frames);
      const protocol::JobStatus s = client::retry_job(http, a.job, frames);
      if (s.frames)
        std::printf("%s: %s again, %lld of %lld frames to render\n", s.id.c_str(), protocol::to_string(s.state),
                    static_cast<long long>(s.frames->queued + s.frames->running + s.frames->paused),
                    static_cast<long long>(s.frames->total));
      else
        std::printf("%s: %s again, %lld of %lld tiles to render\n", s.id.c_str(), protocol::to_string(s.state),
                    static_cast<long long>(s.tiles.total - s.tiles.done), static_cast<long long>(s.tiles.total));
    } else if (!client::cancel_job(http, a.job)) {
      spdlog::error("job {} had already ended", a.job);
      return kExitRefused;
    } else {
      std::printf("%s: cancelled\n", a.job.c_str());
    }
    return kExitOk;
  });
}

}  // namespace tessera::cli
