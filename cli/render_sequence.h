// `tessera render` of a sequence: many frames, one scene file each, rendered one after another in this process
// (`render shot/frame_*.json -o out/frame_####.exr`, `render shot/frame_####.json --frames 1-240 -o ...`).
#pragma once

#include "cli/render_command.h"

namespace tessera::cli {

/// Renders the frames `args.inputs` and `args.frames` name (cli/frame_list.h) one after another, each exactly as
/// `tessera render FRAME.json -o FRAME.exr` with the same options would (render_scene), its output (and --preview)
/// the '#' pattern with the frame's number, and a line per frame on stderr (frame k of N).
///
/// Before rendering anything it refuses (exit 2, a sentence naming the frame or option, nothing written): a frame
/// list cli/frame_list.h refuses; -o, --preview or --resume without a run of '#' for several frames; --crop,
/// --tile-budget with several frames, and --crop with --skip-existing; an output that cannot be written; any frame
/// whose scene does not load. Every frame's scene is loaded up front as its render will load it, short of building
/// it (JSON, values and every asset read, checked and hashed; an image texture that several frames share is
/// decoded once), on all threads.
///
/// --skip-existing skips each frame whose output is complete for these settings (examine_render) and renders the
/// others, saying why. --resume with a '#' pattern takes the sequence's sampling settings from the frame files
/// there, as --resume does from one file (all of them must agree, else it refuses), skips complete frames, continues
/// those --resume can continue and renders the rest. SIGINT or SIGTERM: the frame in progress writes its partial
/// EXR, no later frame starts, exit 130. A frame that fails ends the sequence (exit 1; 2 when nothing was written).
/// With --workers and several frames, the sequence goes to render_farm_sequence (cli/render_farm.h).
int run_render_sequence(const RenderArgs& args);

}  // namespace tessera::cli
