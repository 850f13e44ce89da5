#include "cli/submit_command.h"

#include "protocol/tags.h"

#include "cli/exit_status.h"
#include "cli/frame_list.h"
#include "cli/interrupt_guard.h"
#include "cli/output_check.h"
#include "cli/progress_bar.h"
#include "core/scene/scene_loader.h"
#include "core/util/enum_names.h"
#include "protocol/tags.h"

#include <spdlog/spdlog.h>

#include <algorithm>
#include <chrono>
#include <cstdio>

namespace tessera::cli {

CLI::App* add_submit_command(CLI::App& app, SubmitArgs& a) {
  auto* c = app.add_subcommand("submit", "Submit a scene (or a sequence of frames) to a coordinator and fetch the result");
  add_sequence_flags(c, a.scenes, a.frames, a.frame_order, "");
  add_coordinator_access_flags(c, a.access);
  c->add_option("-o,--output", a.output,
                "Download the finished image to this EXR file (a sequence: a pattern with a run of '#', each frame "
                "written as it finishes)");
  add_sampling_flags(c, a);
  c->add_option("--tile", a.tile_size, "Tile edge in pixels")->check(CLI::Range(1, 4096));
  c->add_option("--priority", a.priority, "Job priority (higher first)");
  c->add_option("--tile-timeout", a.tile_timeout_seconds,
                "Seconds a tile's lease may last from its grant; older leases are revoked and count as a failure of "
                "their worker")
      ->check(CLI::Range(int64_t(1), protocol::kMaxTileTimeoutSeconds))->capture_default_str();
  c->add_option("--name", a.name, "Job label (default: the scene's file name)");
  c->add_option("--require", a.require,
                "Tags a worker must have to render this job, e.g. bigmem,site-a (workers announce theirs with "
                "`worker --tags`)");
  c->add_option("--max-workers", a.max_workers, "Tiles of this job leased at once at most (default: no cap)")
      ->check(CLI::Range(int64_t(0), int64_t(1) << 30));
  c->add_option("--asset-root", a.asset_root, "Allow asset paths anywhere below this folder");
  c->add_flag("--resumable", a.resumable,
              "Keep each tile's exact per-pixel sums, so that `tessera jobs spp ID M` can raise the job's spp later "
              "(bitwise as if submitted at M; docs/resume.md)");
  c->add_option("--after", a.after,
                "Wait until these jobs are done before starting (ID[,ID...]); a failed or cancelled one blocks this job "
                "until it is retried")
      ->delimiter(',');
  c->add_flag("--per-frame", a.per_frame,
              "A sequence after sequences: frame k starts once frame k of each --after job is done");
  c->add_option("--then", a.then,
                "Steps the coordinator runs on the result once the job is done: preview (a full-size PNG), half (a "
                "half-float EXR), contact_sheet (a sequence's frames in one PNG), movie (a sequence's frames as an "
                "H.264 MP4; needs ffmpeg on the coordinator); files under GET /v1/jobs/ID/outputs/NAME, saved by "
                "`tessera jobs outputs ID -o DIR`")
      ->delimiter(',')
      ->check(CLI::IsMember(enum_names(protocol::kStepNames)));
  c->add_option("--fps", a.fps,
                "Frames per second of the movie step's MP4 (default " + std::to_string(protocol::kDefaultMovieFps) +
                    ")")
      ->check(CLI::Range(1, protocol::kMaxMovieFps));
  c->add_option("--notify", a.notify,
                "Also POST this job's end to this URL (allowed by the coordinator's --webhook-allow)");
  c->add_flag("--notify-frames", a.notify_frames,
              "A sequence: also POST each frame done to the --notify URL (event frame.done)");
  c->add_flag("--detach", a.detach, "Print the job id and return without waiting");
  c->add_flag("-q,--quiet", a.quiet, "No progress bar");
  return c;
}

std::vector<client::FrameScene> sequence_frames(const std::vector<std::string>& scenes, const std::string& range,
                                                const std::string& output) {
  std::vector<client::FrameScene> out;
  std::error_code ec;
  if (scenes.size() == 1 && range.empty() && std::filesystem::is_regular_file(scenes.front(), ec)) return out;
  const std::vector<FrameFile> frames = expand_frames(scenes, range);  // throws for a missing file too
  if (!output.empty()) frame_output(output, frames.front().number, frames.size());  // throws without a '#'
  for (const FrameFile& f : frames) out.push_back({f.number, f.scene});
  return out;
}

int follow_job(client::HttpClient& http, const std::string& job, const std::string& output, bool quiet,
               const std::function<bool()>& stop, bool cancel_on_stop, std::chrono::steady_clock::time_point t0,
               const ResultFetch& fetch) {
  try {
    ProgressBar bar(!quiet);
    FrameSaver frames(http, job, output, fetch, quiet);
    const client::JobStatus end = client::wait_for_job(
        http, job,
        [&](const client::JobStatus& s) {
          const double secs = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
          if (s.frames) {
            bar.set_prefix(std::to_string(s.frames->done) + "/" + std::to_string(s.frames->total) + " frames, ");
            if (!output.empty()) frames.update(s);
          }
          bar.update(RenderProgress{int(s.tiles.done), int(s.tiles.total), s.rays, secs});
        },
        stop, std::chrono::milliseconds(200), std::chrono::seconds(120), !quiet || !output.empty());
    if (end.frames && !output.empty()) frames.update(end);  // the frames done since the last event
    if (!end.finished()) {
      if (!cancel_on_stop) {
        std::fprintf(stderr, "stopped waiting: %s is still %s on the coordinator (tessera jobs wait %s -o FILE to fetch "
                     "it later, tessera jobs cancel %s to stop it)\n", job.c_str(), protocol::to_string(end.state),
                     job.c_str(), job.c_str());
        return kExitInterrupted;
      }
      spdlog::warn("interrupted: cancelling {}", job);
      try {
        client::cancel_job(http, job);
      } catch (const std::exception& e) {
        spdlog::warn("cannot cancel {}: {}", job, e.what());
      }
      return kExitFailed;
    }
    const std::string saved =
        end.frames && !output.empty() ? " (" + std::to_string(frames.saved()) + " done frames saved)" : "";
    if (end.state == protocol::JobState::failed) {
      spdlog::error("job {} failed: {}{}", job, end.error.value_or("(no reason given)"), saved);
      return kExitFailed;
    }
    if (end.state == protocol::JobState::cancelled) {
      spdlog::error("job {} was cancelled{}", job, saved);
      return kExitFailed;
    }
    const double secs = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    if (end.frames) {
      if (!quiet)
        std::fprintf(stderr, "%s: %lld frames, %lld tiles, %.2fs (%.2fs from the first lease)\n", job.c_str(),
                     static_cast<long long>(end.frames->total), static_cast<long long>(end.tiles.total), secs,
                     end.render_seconds);
    } else if (!output.empty()) {
      const uint64_t bytes = fetch ? fetch(job, output, 0) : client::download_result(http, job, output);
      if (!quiet)
        std::fprintf(stderr, "%s: %dx%d px, %lld tiles, %.2fs (%.2fs from the first lease), %llu bytes\n",
                     output.c_str(), end.params.width, end.params.height, static_cast<long long>(end.tiles.total), secs,
                     end.render_seconds, static_cast<unsigned long long>(bytes));
    } else if (!quiet) {
      std::fprintf(stderr, "%s done in %.2fs\n", job.c_str(), secs);
    }
    return kExitOk;
  } catch (const std::exception& e) {  // a refusal after the submission too (the job purged meanwhile): the wait failed
    spdlog::error("job {}: {}", job, e.what());
    return kExitFailed;
  }
}

int submit_reporting(client::HttpClient& http, const client::SubmitOptions& o, bool quiet,
                     std::optional<client::SceneFiles> files, std::string& job) {
  try {
    const client::SubmitResult sub =
        files ? client::submit_job(http, o, std::move(*files)) : client::submit_job(http, o);
    job = sub.job_id;
    if (!quiet && o.frames.empty())
      std::fprintf(stderr, "submitted %s as %s (%d assets, %d uploaded)\n", o.scene.c_str(), job.c_str(),
                   sub.assets_total, sub.assets_uploaded);
    else if (!quiet)
      std::fprintf(stderr, "submitted %zu frames (%lld to %lld) as %s (%d distinct assets, %d uploaded)\n",
                   o.frames.size(), static_cast<long long>(o.frames.front().number),
                   static_cast<long long>(o.frames.back().number), job.c_str(), sub.assets_total, sub.assets_uploaded);
    return kExitOk;
  } catch (const client::SubmitError& e) {
    spdlog::error("{}", e.what());
    return kExitRefused;
  } catch (const SceneError& e) {
    spdlog::error("{}", e.what());
    return kExitRefused;
  } catch (const std::exception& e) {
    spdlog::error("{}", e.what());
    return kExitFailed;
  }
}

int submit_and_wait(client::HttpClient& http, const client::SubmitOptions& o, const std::string& output, bool quiet,
                    const std::function<bool()>& stop, std::optional<client::SceneFiles> files, const ResultFetch& fetch) {
  const auto t0 = std::chrono::steady_clock::now();
  std::string job;
  if (const int rc = submit_reporting(http, o, quiet, std::move(files), job)) return rc;
  return follow_job(http, job, output, quiet, stop, true, t0, fetch);
}

int run_submit(const SubmitArgs& a) {
  // A sequence's frames, all found before anything is sent.
  std::vector<client::FrameScene> frames;
  try {
    frames = sequence_frames(a.scenes, a.frames, a.output);
  } catch (const std::invalid_argument& e) {
    spdlog::error("{}", e.what());
    return kExitRefused;
  }
  // Before submitting: a result that could not be saved would waste the farm's work.
  const std::string first_output =
      a.output.empty() || frames.empty() ? a.output : frame_output(a.output, frames.front().number, frames.size()).string();
  if (!first_output.empty() && !output_writable(first_output)) return kExitRefused;
  std::vector<std::string> require;
  try {
    require = protocol::parse_tag_list(a.require, "--require");
  } catch (const std::exception& e) {
    spdlog::error("submit: {}", e.what());
    return kExitRefused;
  }
  if (a.fps && std::find(a.then.begin(), a.then.end(), "movie") == a.then.end()) {
    spdlog::error("submit: --fps is the frame rate of the movie step: it goes with --then movie");
    return kExitRefused;
  }
  return run_with_coordinator(a.access, "submit", [&](client::HttpClient& http) {
    client::SubmitOptions o = shared_job_options(a);
    o.frames = frames;
    o.frame_order = protocol::frame_order_from_string(a.frame_order);
    o.tile_size = a.tile_size;
    o.priority = a.priority;
    o.tile_timeout_seconds = a.tile_timeout_seconds;
    o.name = a.name;
    o.resumable = a.resumable;
    o.require = require;
    o.max_workers = a.max_workers;
    o.pipeline.after = a.after;
    o.pipeline.per_frame = a.per_frame;
    o.pipeline.notify = a.notify;
    o.pipeline.notify_frames = a.notify_frames;
    for (const std::string& step : a.then) o.pipeline.then.push_back(protocol::step_from_string(step));
    if (a.fps) o.pipeline.fps = *a.fps;
    if (a.detach) {
      const client::SubmitResult sub = client::submit_job(http, o);
      std::printf("%s\n", sub.job_id.c_str());
      return kExitOk;
    }
    const auto t0 = std::chrono::steady_clock::now();
    std::string job;
    if (const int rc = submit_reporting(http, o, a.quiet, std::nullopt, job)) return rc;
    // Once the job exists, Ctrl-C stops the wait, not the job: the farm's work goes on and `jobs wait` fetches it.
    InterruptGuard interrupts;
    return follow_job(http, job, a.output, a.quiet, [] { return InterruptGuard::interrupted(); }, false, t0);
  });
}

}  // namespace tessera::cli
