// The single `tessera` executable: one subcommand per way of using the farm, one rule for exit statuses
// (cli/exit_status.h).
#include "cli/build_commit.h"
#include "cli/exit_status.h"
#include "cli/jobs_command.h"
#include "cli/merge_command.h"
#include "cli/render_command.h"
#include "cli/serve_command.h"
#include "cli/submit_command.h"
#include "cli/worker_command.h"
#include "cli/workers_command.h"

#include <CLI/CLI.hpp>
#include <spdlog/spdlog.h>

#include <cstdio>
#include <exception>

int main(int argc, char** argv) {
  try {
    CLI::App app{"Tessera: a render-farm tile service"};
    // --version: the release number and the commit it was built from, e.g. "tessera 0.1.0 (commit 03cac3c)".
    app.set_version_flag("--version", std::string("tessera ") + TESSERA_VERSION + " (commit " +
                                          tessera::cli::build_commit() + ")");
    app.require_subcommand(0, 1);

    tessera::cli::RenderArgs render_args;
    auto* render = tessera::cli::add_render_command(app, render_args);
    tessera::cli::ServeArgs serve_args;
    auto* serve = tessera::cli::add_serve_command(app, serve_args);
    tessera::cli::WorkerArgs worker_args;
    auto* worker = tessera::cli::add_worker_command(app, worker_args);
    tessera::cli::SubmitArgs submit_args;
    auto* submit = tessera::cli::add_submit_command(app, submit_args);
    tessera::cli::JobsArgs jobs_args;
    auto* jobs = tessera::cli::add_jobs_command(app, jobs_args);
    tessera::cli::WorkersArgs workers_args;
    auto* workers = tessera::cli::add_workers_command(app, workers_args);
    tessera::cli::MergeArgs merge_args;
    auto* merge = tessera::cli::add_merge_command(app, merge_args);

    try {
      app.parse(argc, argv);
    } catch (const CLI::ParseError& e) {
      // --help and --version exit 0; any other parse error is a refused command line, like the commands' own checks
      // (CLI11 would exit 105-109 by the kind of error).
      return app.exit(e) == 0 ? tessera::cli::kExitOk : tessera::cli::kExitRefused;
    }

    if (render->parsed()) return tessera::cli::run_render(render_args);
    if (serve->parsed()) return tessera::cli::run_serve(serve_args);
    if (worker->parsed()) return tessera::cli::run_worker_command(worker_args);
    if (submit->parsed()) return tessera::cli::run_submit(submit_args);
    if (jobs->parsed()) return tessera::cli::run_jobs(jobs_args);
    if (workers->parsed()) return tessera::cli::run_workers(workers_args);
    if (merge->parsed()) return tessera::cli::run_merge(merge_args);
    std::fputs(app.help().c_str(), stdout);
    return tessera::cli::kExitOk;
  } catch (const std::exception& e) {
    spdlog::error("{}", e.what());
    return tessera::cli::kExitFailed;
  }
}
