// The movie step's encoder: a sequence's frames, tone-mapped like the preview step (8-bit sRGB), fed as raw RGB on
// the standard input of Debian's ffmpeg, which writes an H.264 MP4 (yuv420p; an odd width or height padded by one
// black column or row). ffmpeg runs with a fixed argument vector and an empty environment, no shell; its output goes
// to a log file whose end a failure quotes.
#pragma once

#include "protocol/pipeline.h"

#include <filesystem>
#include <functional>
#include <stdexcept>
#include <vector>

namespace tessera::server {

/// Thrown when the encoder was stopped before it finished (the coordinator shutting down): the movie is not failed,
/// it is made again after the restart.
struct EncodeInterrupted : std::runtime_error {
  using std::runtime_error::runtime_error;
};

/// What encode_movie needs.
struct MovieJob {
  std::filesystem::path ffmpeg;               ///< The executable to run.
  std::vector<std::filesystem::path> frames;  ///< The frames' EXR results, in play order, all of one size.
  int fps = protocol::kDefaultMovieFps;       ///< Frames per second.
  std::filesystem::path output;               ///< The MP4 written (replaced whole, only when ffmpeg succeeded).
  std::filesystem::path log;                  ///< ffmpeg's standard output and error (overwritten).
  double stall_seconds = 600;                 ///< ffmpeg killed, and the step failed, after this long without progress.
};

/// Encodes the movie. Throws std::runtime_error with a sentence (for a failed ffmpeg: how it ended and the end of its
/// log; for one that neither read a frame nor, once fed, exited within MovieJob::stall_seconds: that, after killing it), or EncodeInterrupted when `stopping` turned true before ffmpeg exited (it is looked at between frames and
/// every 50 ms while ffmpeg is waited for; ffmpeg is then killed). Leaves no partial output either way.
void encode_movie(const MovieJob& job, const std::function<bool()>& stopping);

}  // namespace tessera::server
