// `tessera render --resume FILE`: the settings a resumable EXR records, turned back into render arguments.
#pragma once

#include "cli/render_command.h"
#include "core/image/image.h"
#include "protocol/messages.h"

#include <cstdint>
#include <map>
#include <string>

namespace tessera::cli {

/// `given` with the sampling settings of the render stored in `file` (seed, spp unless given, crop window,
/// variance, replicates, adaptive settings, strategies). Throws Refusal (cli/exit_status.h) naming `given.resume` when the
/// file lacks them, is not a render of this kind, or --spp asks for something that cannot be continued exactly.
RenderArgs resumed_args(const RenderArgs& given, const ExrImage& file);

/// The samples per pixel recorded in a resumable file's metadata (0 for an adaptive render).
uint32_t recorded_spp(const ExrImage& file);

}  // namespace tessera::cli
