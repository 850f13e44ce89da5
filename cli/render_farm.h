// `tessera render --workers N`: the same render through a private coordinator and N local worker processes.
#pragma once

#include "cli/frame_list.h"
#include "cli/render_command.h"
#include "client/job_client.h"

#include <vector>

namespace tessera::cli {

/// Runs a coordinator on a loopback port in this process (cli/private_coordinator.h; its log in the scratch folder's
/// serve.log) and starts N `tessera worker`s, submits the scene through the farm protocol, shows progress, writes the
/// EXR, and stops the workers (SIGTERM, then SIGKILL after a grace period) and the coordinator whatever happens,
/// Ctrl-C included. With `frames`, the sequence is one job and each frame's EXR (and preview) is written to
/// its '#' pattern as it finishes. Returns the process exit code.
int run_render_farm(const RenderArgs& args, const std::vector<client::FrameScene>& frames = {});

/// `tessera render --workers N` of several frames, sorted by number. run_render_sequence (cli/render_sequence.h) hands
/// them over once the frame list and the sequence's options are accepted (`args.output`, and `args.preview` and
/// `args.resume` when given, are '#' patterns), before checking outputs and scenes. The sequence is one job of the
/// private farm (run_render_farm); --skip-existing and --resume are refused (exit 2): they belong to a render in
/// this process.
int render_farm_sequence(const RenderArgs& args, const std::vector<FrameFile>& frames);

}  // namespace tessera::cli
