// `tessera submit`: send a scene to a coordinator, follow its progress, download the result.
#pragma once

#include "cli/coordinator_access.h"
#include "client/http_client.h"
#include "client/job_client.h"

#include <CLI/CLI.hpp>

#include <cstdint>
#include <functional>
#include <optional>
#include <string>

namespace tessera::cli {

/// Options of `tessera submit`.
struct SubmitArgs {
  std::string scene;                ///< Scene file.
  std::string output;               ///< Where to write result.exr (empty: do not download).
  std::optional<uint32_t> spp;      ///< Samples per pixel override.
  int tile_size = protocol::kDefaultTileSize;  ///< Tile edge.
  int priority = protocol::kDefaultPriority;   ///< Job priority.
  int64_t tile_timeout_seconds = protocol::kDefaultTileTimeoutSeconds;  ///< --tile-timeout.
  uint64_t seed = 0;                ///< Sample seed.
  std::string name;                 ///< Job label.
  std::string integrator;           ///< "direct": submit scenes of other integrator types.
  std::string asset_root;           ///< Allow assets anywhere below this folder.
  double target_error = 0.0;        ///< Adaptive sampling target (0: off).
  uint32_t min_spp = protocol::kDefaultMinSpp;  ///< Adaptive sampling: first round.
  uint32_t max_spp = protocol::kDefaultMaxSpp;  ///< Adaptive sampling: most samples per pixel.
  CoordinatorAccess access;         ///< Coordinator URL, token and TLS files.
  bool resumable = false;           ///< Keep each tile's exact sums so `jobs spp` can raise the job's spp later.
  bool detach = false;              ///< Print the job id and return without waiting.
  bool quiet = false;               ///< No progress bar.
};

/// The job settings `submit` and `render --workers` share, from either's arguments (the fields have the same names);
/// the caller adds the tile size, priority and name.
template <class Args>
farm::SubmitOptions shared_job_options(const Args& a) {
  farm::SubmitOptions o;
  o.scene = a.scene;
  o.sampling.spp = a.spp.value_or(0);
  o.sampling.seed = a.seed;
  if (!a.integrator.empty()) o.sampling.integrator = "direct";
  if (!a.asset_root.empty()) o.asset_root = a.asset_root;
  o.sampling.target_error = a.target_error;
  o.sampling.min_spp = a.min_spp;
  o.sampling.max_spp = a.max_spp;
  return o;
}

/// Registers the subcommand's options on `app`.
CLI::App* add_submit_command(CLI::App& app, SubmitArgs& args);

/// Runs it; returns the process exit code: 0 done (and downloaded), 1 failed/cancelled or transport errors, 2 refused.
int run_submit(const SubmitArgs& args);

/// Submits, shows progress until the job ends and downloads the result to `output` (when not empty); the shared
/// core of `submit` and `render --workers`. stop() interrupts the wait (the job is then cancelled). Returns the exit
/// code as run_submit does; reports errors itself. `files`, when given, is the scene as already read and hashed
/// (farm::read_scene_files of the same options).
int submit_and_wait(farm::HttpClient& http, const farm::SubmitOptions& options, const std::string& output, bool quiet,
                    const std::function<bool()>& stop, std::optional<farm::SceneFiles> files = std::nullopt);

}  // namespace tessera::cli
