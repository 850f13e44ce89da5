// `tessera render` of a sequence: each frame rendered as `tessera render FRAME.json` renders it, one after another in
// this process (or through a private farm with --workers), its file written as it finishes.
#pragma once

#include "cli/frame_list.h"
#include "cli/render_command.h"

#include <vector>

namespace tessera::cli {

/// Renders `frames` with the options of `args` (whose output and preview are '#' patterns); returns the exit code
/// as run_render does: the first frame's failure or interruption stops the sequence with its code.
int render_sequence(const RenderArgs& args, const std::vector<FrameFile>& frames);

/// Why the file `output` is not a complete render of `scene` with the sampling settings of `args` (a sentence), or
/// "" when it is (then a sequence with --skip-existing skips the frame). Decided from the file's own metadata: it
/// reads, is not partial, and records the scene's hash and these sampling settings.
std::string incomplete_reason(const RenderArgs& args, const std::filesystem::path& scene,
                              const std::filesystem::path& output);

}  // namespace tessera::cli
