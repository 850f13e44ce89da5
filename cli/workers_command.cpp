#include "cli/workers_command.h"

#include "cli/exit_status.h"
#include "cli/progress_bar.h"

#include "client/http_client.h"
#include "client/job_client.h"

#include <spdlog/spdlog.h>

#include <chrono>
#include <cstdio>

namespace tessera::cli {

namespace {

// One line per worker: id, state, threads, tiles done, its rate on them, what it renders, seconds since seen, tags,
// name, blocklists.
void print_table(const std::vector<protocol::WorkerInfo>& workers) {
  const int64_t now = std::chrono::duration_cast<std::chrono::milliseconds>(
                          std::chrono::system_clock::now().time_since_epoch()).count();
  std::printf("%-14s %-10s %7s %6s %8s %-26s %6s %-16s  %s\n", "ID", "STATE", "THREADS", "TILES", "MRAYS/S", "RENDERING",
              "SEEN", "TAGS", "NAME");
  for (const protocol::WorkerInfo& w : workers) {
    const std::string doing = w.job ? *w.job + " #" + std::to_string(w.tile.value_or(0)) : "-";
    const std::string seen = std::to_string((now - w.last_seen_ms) / 1000) + "s";
    std::string blocked;
    for (const std::string& j : w.blocklisted_for) blocked += (blocked.empty() ? "  blocklisted for " : ", ") + j;
    std::string tags;
    for (const std::string& t : w.tags) tags += (tags.empty() ? "" : ",") + t;
    std::printf("%-14s %-10s %7lld %6lld %8s %-26s %6s %-16s  %s%s\n", w.id.c_str(), protocol::to_string(w.state),
                static_cast<long long>(w.threads), static_cast<long long>(w.tiles_done),
                format_mrays(w.rays, w.render_seconds).c_str(), doing.c_str(), seen.c_str(),
                tags.empty() ? "-" : tags.c_str(), w.name.c_str(), blocked.c_str());
  }
}

}  // namespace

CLI::App* add_workers_command(CLI::App& app, WorkersArgs& a) {
  auto* c = app.add_subcommand("workers", "List a coordinator's workers, drain or undrain one");
  c->add_option("action", a.action, "ls: list; drain ID: finish the current tile, then take no more; undrain ID")
      ->required()
      ->check(CLI::IsMember({"ls", "drain", "undrain"}));
  c->add_option("worker", a.worker, "Worker id (drain, undrain)");
  add_coordinator_access_flags(c, a.access);
  return c;
}

int run_workers(const WorkersArgs& a) {
  if (a.action != "ls" && a.worker.empty()) {
    spdlog::error("workers {} needs a worker id", a.action);
    return kExitRefused;
  }
  return run_with_coordinator(a.access, "workers " + a.action, [&](client::HttpClient& http) {
    if (a.action == "ls") {
      print_table(client::list_workers(http));
    } else {
      const protocol::WorkerInfo w = client::drain_worker(http, a.worker, a.action == "drain");
      std::printf("%s: %s\n", w.id.c_str(), protocol::to_string(w.state));
    }
    return kExitOk;
  });
}

}  // namespace tessera::cli
