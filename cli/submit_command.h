// `tessera submit`: send a scene to a coordinator, follow its progress, download the result.
#pragma once

#include "cli/coordinator_access.h"
#include "cli/frame_saver.h"
#include "cli/sampling_flags.h"
#include "client/http_client.h"
#include "client/job_client.h"

#include <CLI/CLI.hpp>

#include <chrono>
#include <cstdint>
#include <functional>
#include <optional>
#include <string>
#include <vector>

namespace tessera::cli {

/// Options of `tessera submit` (the sampling ones are those `render` has too).
struct SubmitArgs : SamplingArgs {
  std::vector<std::string> scenes;  ///< Scene file, or a sequence's frame files or '#' pattern.
  std::string frames;               ///< --frames: the range a '#' pattern is expanded over.
  std::string frame_order = protocol::to_string(protocol::FrameOrder::in_order);  ///< --frame-order of a sequence.
  std::string output;               ///< Where to write result.exr (a sequence: a '#' pattern; empty: do not download).
  int tile_size = protocol::kDefaultTileSize;  ///< Tile edge.
  int priority = protocol::kDefaultPriority;   ///< Job priority.
  int64_t tile_timeout_seconds = protocol::kDefaultTileTimeoutSeconds;  ///< --tile-timeout.
  std::string name;                 ///< Job label.
  std::string asset_root;           ///< Allow assets anywhere below this folder.
  CoordinatorAccess access;         ///< Coordinator URL, token and TLS files.
  bool resumable = false;           ///< Keep each tile's exact sums so `jobs spp` can raise the job's spp later.
  std::string require;              ///< --require: tags a worker must have, comma-separated.
  int64_t max_workers = 0;          ///< --max-workers: tiles leased at once at most (0: no cap).
  bool detach = false;              ///< Print the job id and return without waiting.
  bool quiet = false;               ///< No progress bar.
  std::vector<std::string> after;   ///< --after: jobs that must be done before this one starts.
  bool per_frame = false;           ///< --per-frame: frame k of the sequence waits for frame k of each --after job.
  std::string notify;               ///< --notify: the job's own webhook address.
  bool notify_frames = false;       ///< --notify-frames: --notify is also told of each frame done.
  std::vector<std::string> then;    ///< --then: steps run on the result once the job is done.
  std::optional<int> fps;           ///< --fps: the movie step's frame rate.
};

/// The job settings `submit` and `render --workers` share, from either's arguments (the fields have the same names):
/// the scene, where its assets may lie, and every sampling setting; the caller adds the tile size, priority and name.
template <class Args>
client::SubmitOptions shared_job_options(const Args& a) {
  client::SubmitOptions o;
  o.scene = a.scenes.front();
  if (!a.asset_root.empty()) o.asset_root = a.asset_root;
  o.sampling = sampling_settings(a, a.spp.value_or(0));  // 0: the scene's spp
  return o;
}

/// Registers the subcommand's options on `app`.
CLI::App* add_submit_command(CLI::App& app, SubmitArgs& args);

/// Runs it; returns the process exit code: 0 done (and downloaded), 1 failed/cancelled or transport errors, 2 refused,
/// 130 stopped waiting by Ctrl-C or SIGTERM (the job goes on; `jobs wait` fetches it later).
int run_submit(const SubmitArgs& args);

/// The frames of a sequence named by `scenes` and `range` (cli/frame_list.h) as submit options take them, and checks
/// that `output` (when not empty) names a file per frame; nothing for one scene. Throws std::invalid_argument with
/// the sentence to report (exit status 2).
std::vector<client::FrameScene> sequence_frames(const std::vector<std::string>& scenes, const std::string& range,
                                                const std::string& output);

/// Follows a submitted job until it ends, with a progress bar (timed from t0) unless `quiet`, and saves its result to
/// `output` (when not empty; a sequence saves each frame as it finishes, `output` being a '#' pattern); the shared
/// core of `submit`, `render --workers` and `jobs wait`. stop() ends the wait
/// early: the job is then cancelled when `cancel_on_stop` (exit code 1), else left as it is, which it says (130).
/// Returns the exit code as run_submit does; reports errors itself. `fetch`, when given, takes the result instead
/// of the download.
int follow_job(client::HttpClient& http, const std::string& job, const std::string& output, bool quiet,
               const std::function<bool()>& stop, bool cancel_on_stop, std::chrono::steady_clock::time_point t0,
               const ResultFetch& fetch = {});

/// Submits (uploading the assets the coordinator lacks) and sets `job` to the new job's id; says so unless `quiet`.
/// Returns 0, or the exit code as run_submit does after reporting the error. `files`, when given, is the scene as
/// already read and hashed (client::read_scene_files of the same options).
int submit_reporting(client::HttpClient& http, const client::SubmitOptions& options, bool quiet,
                     std::optional<client::SceneFiles> files, std::string& job);

/// Submits, then follows the job as follow_job does (stop() cancels it); the shared core of `submit` and `render
/// --workers`. Returns the exit code as run_submit does; reports errors itself. `files` as for submit_reporting,
/// `fetch` as for follow_job.
int submit_and_wait(client::HttpClient& http, const client::SubmitOptions& options, const std::string& output, bool quiet,
                    const std::function<bool()>& stop, std::optional<client::SceneFiles> files = std::nullopt,
                    const ResultFetch& fetch = {});

}  // namespace tessera::cli
