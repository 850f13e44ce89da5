// The single `tessera` executable: one subcommand per way of using the farm, one rule for exit statuses
// (cli/exit_status.h).
#include "cli/audit_command.h"
#include "cli/build_commit.h"
#include "cli/contact_sheet_command.h"
#include "cli/exit_status.h"
#include "cli/jobs_command.h"
#include "cli/merge_command.h"
#include "cli/render_command.h"
#include "cli/serve_command.h"
#include "cli/submit_command.h"
#include "cli/users_command.h"
#include "cli/worker_command.h"
#include "cli/workers_command.h"

#include <CLI/CLI.hpp>
#include <spdlog/spdlog.h>

#include <cstdio>
#include <exception>
#include <functional>
#include <memory>
#include <vector>

namespace {

// A subcommand: what CLI11 parsed it into, and what runs it with the arguments it was given.
struct Command {
  CLI::App* app;
  std::function<int()> run;
};

template <class Args>
Command command(CLI::App& app, CLI::App* (*add)(CLI::App&, Args&), int (*run)(const Args&)) {
  auto args = std::make_shared<Args>();
  return {add(app, *args), [args, run] { return run(*args); }};
}

}  // namespace

int main(int argc, char** argv) {
  try {
    CLI::App app{"Tessera: a render-farm tile service"};
    // --version: the release number and the commit it was built from, e.g. "tessera 0.1.0 (commit 03cac3c)".
    app.set_version_flag("--version", std::string("tessera ") + TESSERA_VERSION + " (commit " +
                                          tessera::cli::build_commit() + ")");
    app.require_subcommand(0, 1);

    namespace c = tessera::cli;
    const std::vector<Command> commands = {command(app, c::add_render_command, c::run_render),
                                           command(app, c::add_serve_command, c::run_serve),
                                           command(app, c::add_worker_command, c::run_worker_command),
                                           command(app, c::add_submit_command, c::run_submit),
                                           command(app, c::add_jobs_command, c::run_jobs),
                                           command(app, c::add_workers_command, c::run_workers),
                                           command(app, c::add_merge_command, c::run_merge),
                                           command(app, c::add_contact_sheet_command, c::run_contact_sheet),
                                           command(app, c::add_users_command, c::run_users),
                                           command(app, c::add_audit_command, c::run_audit)};

    try {
      app.parse(argc, argv);
    } catch (const CLI::ParseError& e) {
      // --help and --version exit 0; any other parse error is a refused command line, like the commands' own checks
      // (CLI11 would exit 105-109 by the kind of error).
      return app.exit(e) == 0 ? tessera::cli::kExitOk : tessera::cli::kExitRefused;
    }

    for (const Command& cmd : commands)
      if (cmd.app->parsed()) return cmd.run();
    std::fputs(app.help().c_str(), stdout);
    return tessera::cli::kExitOk;
  } catch (const std::exception& e) {
    spdlog::error("{}", e.what());
    return tessera::cli::kExitFailed;
  }
}
