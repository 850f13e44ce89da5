#include "cli/jobs_command.h"

#include "cli/tls_flags.h"
#include "cli/token.h"
#include "worker/http_client.h"
#include "worker/job_client.h"

#include <nlohmann/json.hpp>
#include <spdlog/spdlog.h>

#include <cstdio>

namespace tessera::cli {

namespace {

// One line per job: id, state, priority, tiles done/total, name.
void print_table(const std::vector<protocol::JobStatus>& jobs) {
  std::printf("%-20s %-10s %8s %13s  %s\n", "ID", "STATE", "PRIORITY", "TILES", "NAME");
  for (const protocol::JobStatus& j : jobs) {
    const std::string tiles = std::to_string(j.tiles.done) + "/" + std::to_string(j.tiles.total);
    std::printf("%-20s %-10s %8d %13s  %s\n", j.id.c_str(), protocol::to_string(j.state), j.params.priority,
                tiles.c_str(), j.params.name.c_str());
  }
}

// One line per tile (index, state, worker, attempts, render seconds, rays, failing workers), then each failure with the
// log lines its worker sent.
void print_tiles(const protocol::TileList& list) {
  std::printf("%6s %-8s %-24s %8s %9s %14s %8s\n", "TILE", "STATE", "WORKER", "ATTEMPTS", "SECONDS", "RAYS", "FAILURES");
  for (const protocol::TileInfo& t : list.tiles) {
    const std::string worker = t.worker ? *t.worker + (t.worker_name && !t.worker_name->empty() ? " (" + *t.worker_name + ")" : "") : "-";
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
}

}  // namespace

CLI::App* add_jobs_command(CLI::App& app, JobsArgs& a) {
  auto* c = app.add_subcommand("jobs", "List and control a coordinator's jobs");
  c->add_option("action", a.action, "ls: list; show ID: the job as JSON; pause ID: no new leases (running tiles "
                                    "finish); resume ID; tiles ID: one line per tile, then failures with their log "
                                    "lines; requeue ID N: render tile N again; priority ID N: lease its tiles in a new order; retry ID: render a failed or cancelled job's missing tiles; "
                                    "cancel ID")
      ->required()
      ->check(CLI::IsMember({"ls", "show", "tiles", "requeue", "pause", "resume", "priority", "retry", "cancel"}));
  c->add_option("job", a.job, "Job id (all but ls)");
  c->add_option("priority", a.priority, "New priority, higher runs first (priority); the tile number (requeue)");
  c->add_flag("--tiles", a.tiles, "show: print the tile table after the job");
  c->add_option("--coordinator", a.coordinator, "Coordinator URL, e.g. http://127.0.0.1:8470")->required();
  c->add_option("--token-file", a.token_file, "File holding the client token (default: $TESSERA_CLIENT_TOKEN)");
  add_client_tls_flags(c, a.tls);
  return c;
}

int run_jobs(const JobsArgs& a) {
  if (a.action != "ls" && a.job.empty()) {
    spdlog::error("jobs {} needs a job id", a.action);
    return 2;
  }
  if (a.action == "priority" && !a.priority) {
    spdlog::error("jobs priority needs a job id and the new priority");
    return 2;
  }
  if (a.action == "requeue" && !a.priority) {
    spdlog::error("jobs requeue needs a job id and a tile number");
    return 2;
  }
  try {
    farm::HttpClient http(farm::parse_http_url(a.coordinator), {}, uint64_t(2) << 30, a.tls);
    http.set_bearer_token(load_token(a.token_file, "TESSERA_CLIENT_TOKEN"));
    if (a.action == "ls") {
      print_table(farm::list_jobs(http));
    } else if (a.action == "show") {
      std::printf("%s\n", nlohmann::json(farm::get_job(http, a.job)).dump(2).c_str());
      if (a.tiles) print_tiles(farm::get_job_tiles(http, a.job));
    } else if (a.action == "tiles") {
      print_tiles(farm::get_job_tiles(http, a.job));
    } else if (a.action == "requeue") {
      const protocol::TileInfo t = farm::requeue_tile(http, a.job, *a.priority);
      std::printf("%s tile %lld: %s again\n", a.job.c_str(), static_cast<long long>(t.index), t.state.c_str());
    } else if (a.action == "pause" || a.action == "resume") {
      const protocol::JobStatus s = a.action == "pause" ? farm::pause_job(http, a.job) : farm::resume_job(http, a.job);
      std::printf("%s: %s\n", s.id.c_str(), protocol::to_string(s.state));
    } else if (a.action == "priority") {
      const protocol::JobStatus s = farm::set_job_priority(http, a.job, *a.priority);
      std::printf("%s: %s, priority %d\n", s.id.c_str(), protocol::to_string(s.state), s.params.priority);
    } else if (a.action == "retry") {
      const protocol::JobStatus s = farm::retry_job(http, a.job);
      std::printf("%s: %s again, %lld of %lld tiles to render\n", s.id.c_str(), protocol::to_string(s.state),
                  static_cast<long long>(s.tiles.total - s.tiles.done), static_cast<long long>(s.tiles.total));
    } else if (!farm::cancel_job(http, a.job)) {
      spdlog::error("job {} had already ended", a.job);
      return 2;
    } else {
      std::printf("%s: cancelled\n", a.job.c_str());
    }
    return 0;
  } catch (const farm::SubmitError& e) {
    spdlog::error("{}", e.what());
    return 2;
  } catch (const std::exception& e) {
    spdlog::error("jobs {}: {}", a.action, e.what());
    return 1;
  }
}

}  // namespace tessera::cli
