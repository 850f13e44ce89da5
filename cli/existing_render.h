// Whether a file an earlier `tessera render` wrote is already the render a command would make, or one that --resume
// can continue into it; judged from the file itself (its metadata, windows and channels, and that its pixels read),
// never from its presence. `render --skip-existing` and a sequence's --resume decide each frame with it.
#pragma once

#include "cli/render_command.h"

#include <cstdint>
#include <filesystem>
#include <map>
#include <set>
#include <string>

namespace tessera::cli {

/// What a render writes, as far as its file records it.
struct ExpectedRender {
  std::string scene_hash;                       ///< tessera:sceneHash of the scene.
  int width = 0;                                ///< The picture's width: display and data window (no crop).
  int height = 0;                               ///< Its height.
  std::map<std::string, std::string> sampling;  ///< protocol::SamplingSettings::metadata() of the render's settings.
  bool half = false;                            ///< Colours stored as half floats (--half).
  bool variance = false;                        ///< variance.R/G/B channels (--variance).
  bool resumable = false;                       ///< Exact sample sums (--resumable); files that have them when not
                                                ///< asked for still count as complete.
};

/// The render `args` make of a scene with this hash, size and own spp (used when args give no --spp).
ExpectedRender expected_render(const RenderArgs& args, const std::string& scene_hash, int width, int height,
                               uint32_t scene_spp);

/// An existing file judged against an ExpectedRender.
struct ExistingRender {
  bool exists = false;       ///< Something is at the path.
  bool complete = false;     ///< It is the expected render, finished: nothing is left to do.
  /// --resume can make the expected render from it: a partial render of the same scene and settings (at its own spp,
  /// or at fewer with exact sums), or a finished one with exact sums at fewer spp.
  bool continuable = false;
  std::string why_incomplete;       ///< When it exists and is not complete: why, said after its name.
  std::string why_not_continuable;  ///< When it exists and is not continuable: why, said after its name.
};

/// Judges the file at `path`: its header first (read_exr_header), then, when it is complete or continuable by its
/// header, that all its pixels read. Never throws for the file's content; a file that does not read is neither.
ExistingRender examine_render(const std::filesystem::path& path, const ExpectedRender& expected);

/// The metadata keys that record a render's sampling settings (those protocol::SamplingSettings::metadata() writes).
const std::set<std::string>& sampling_keys();

/// The first difference between the sampling settings `file` records and `expected` (keys of sampling_keys() other
/// than `ignored`), as "tessera:seed 3, not 7" or "no tessera:bvhOverride, not median"; empty when they agree.
std::string sampling_difference(const std::map<std::string, std::string>& file,
                                const std::map<std::string, std::string>& expected, const std::string& ignored = "");

}  // namespace tessera::cli
