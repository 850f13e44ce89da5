// `tessera render --workers N`: the same render through a private coordinator and N local worker processes.
#pragma once

#include "cli/render_command.h"
#include "client/job_client.h"

#include <vector>

namespace tessera::cli {

/// Starts `tessera serve` on a loopback port and N `tessera worker`s, submits the scene through the farm protocol,
/// shows progress, writes the EXR, and stops the children (SIGTERM, then SIGKILL after a grace period) whatever
/// happens, Ctrl-C included. With `frames`, the sequence is one job and each frame's EXR (and preview) is written to
/// its '#' pattern as it finishes. Returns the process exit code.
int run_render_farm(const RenderArgs& args, const std::vector<client::FrameScene>& frames = {});

}  // namespace tessera::cli
