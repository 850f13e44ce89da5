// The single `tessera` executable: one subcommand per way of using the farm.
#include "cli/render_command.h"
#include "cli/serve_command.h"

#include <CLI/CLI.hpp>
#include <spdlog/spdlog.h>

#include <cstdio>
#include <exception>

namespace {

int not_yet(const char* what) {
  spdlog::error("'tessera {}' is not implemented yet in this version", what);
  return 2;
}

}  // namespace

int main(int argc, char** argv) {
  try {
    CLI::App app{"Tessera: a render-farm tile service"};
    app.set_version_flag("--version", std::string("tessera ") + TESSERA_VERSION);
    app.require_subcommand(0, 1);

    tessera::cli::RenderArgs render_args;
    auto* render = tessera::cli::add_render_command(app, render_args);
    tessera::cli::ServeArgs serve_args;
    auto* serve = tessera::cli::add_serve_command(app, serve_args);
    auto* worker = app.add_subcommand("worker", "Run a worker that leases and renders tiles");
    auto* submit = app.add_subcommand("submit", "Submit a scene to a coordinator and fetch the result");
    auto* merge = app.add_subcommand("merge", "Assemble cropped EXR tiles into one image");

    CLI11_PARSE(app, argc, argv);

    if (render->parsed()) return tessera::cli::run_render(render_args);
    if (serve->parsed()) return tessera::cli::run_serve(serve_args);
    if (worker->parsed()) return not_yet("worker");
    if (submit->parsed()) return not_yet("submit");
    if (merge->parsed()) return not_yet("merge");
    std::fputs(app.help().c_str(), stdout);
    return 0;
  } catch (const std::exception& e) {
    spdlog::error("{}", e.what());
    return 1;
  }
}
