// A job's place in a pipeline (docs/protocol.md, "Pipelines"), fixed at submission: the jobs it waits for, the steps
// the coordinator runs on its result, and the address told when it ends.
#pragma once

#include "core/util/enum_names.h"

#include <nlohmann/json_fwd.hpp>

#include <cstddef>
#include <string>
#include <string_view>
#include <vector>

namespace tessera::protocol {

/// The most jobs one submission may wait for.
inline constexpr size_t kMaxDependencies = 64;
/// The longest job id a dependency may name.
inline constexpr size_t kMaxJobIdBytes = 200;
/// The longest webhook address a submission may give.
inline constexpr size_t kMaxWebhookUrlBytes = 2048;
/// Frames per second of the movie step's MP4 unless the submission says otherwise ("fps").
inline constexpr int kDefaultMovieFps = 24;
/// The highest frame rate a movie may ask for.
inline constexpr int kMaxMovieFps = 240;

/// A built-in step the coordinator runs on a finished job's result (no other command ever runs).
enum class Step {
  preview,        ///< A tone-mapped PNG of each image at full size.
  half,           ///< A half-float copy of each EXR.
  contact_sheet,  ///< A sequence: one PNG of every frame side by side.
  movie,          ///< A sequence: an H.264 MP4 of its frames (needs ffmpeg on the coordinator).
};
/// The protocol's name of each step, in declaration order.
inline constexpr std::string_view kStepNames[] = {"preview", "half", "contact_sheet", "movie"};
/// The protocol's name of a step.
inline const char* to_string(Step s) { return enum_c_name(s, kStepNames); }
/// Parses a step name; throws std::invalid_argument for unknown names.
inline Step step_from_string(std::string_view s) { return enum_from_name_or_throw<Step>(s, kStepNames, "step"); }

/// What a job does besides rendering.
struct Pipeline {
  std::vector<std::string> after;  ///< Jobs that must be done before it starts (no duplicates).
  /// A sequence after sequences: its frame k waits only for their frame k (else every frame waits for the whole jobs).
  bool per_frame = false;
  std::vector<Step> then;  ///< Steps run on its result once it is done, in this order (no duplicates).
  int fps = kDefaultMovieFps;  ///< Frames per second of the movie step's MP4.
  std::string notify;      ///< A webhook address told when it ends or is blocked ("": none but the farm's own).
  bool notify_frames = false;  ///< A sequence: `notify` is also told of each frame done (event "frame.done").
  /// True when it is the default (no dependency, no step, no address).
  bool empty() const {
    return after.empty() && !per_frame && then.empty() && fps == kDefaultMovieFps && notify.empty() && !notify_frames;
  }
};

/// Where a step of a done job is: "pending" (queued or running), "done" (its files listed) or "failed" (its log).
struct StepOutput {
  Step step = Step::preview;         ///< Which step.
  std::string state;                 ///< pending, done or failed.
  std::vector<std::string> files;    ///< done: its files (GET /v1/jobs/{id}/outputs/{name}).
  std::string log;                   ///< failed: what it said.
};
void to_json(nlohmann::json& j, const StepOutput& o);
void from_json(const nlohmann::json& j, StepOutput& o);

/// Writes the pipeline's fields into an object (a submission or a job), leaving out those at their defaults.
void put_pipeline(nlohmann::json& j, const Pipeline& p);
/// Reads the pipeline fields of a submission ("after", "per_frame", "then", "fps", "notify", "notify_frames"), checking
/// their types, sizes and that each goes with what it needs;
/// throws ProtocolError with the sentence the coordinator answers (400).
Pipeline request_pipeline(const nlohmann::json& j);
/// Reads the pipeline fields of an answer (a job), tolerating absent ones; throws ProtocolError on wrong types.
Pipeline answer_pipeline(const nlohmann::json& j);

}  // namespace tessera::protocol
