// `tessera merge`: assemble EXR tiles written by `tessera render --crop` into the full image.
#pragma once

#include <CLI/CLI.hpp>

#include <string>
#include <vector>

namespace tessera::cli {

/// Options of `tessera merge`.
struct MergeArgs {
  std::vector<std::string> inputs;  ///< Tile EXRs.
  std::string output;               ///< EXR to write.
  bool half = false;                ///< Write half floats.
  bool multipart = false;           ///< Write one EXR part per output layer.
};

/// Registers the subcommand's options on `app`.
CLI::App* add_merge_command(CLI::App& app, MergeArgs& args);

/// Runs it; returns the process exit code (errors are reported, never thrown).
int run_merge(const MergeArgs& args);

}  // namespace tessera::cli
