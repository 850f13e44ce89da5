// Which frames a command line names (scene files, or a '#' pattern with a range) and where each frame's output goes.
#pragma once

#include <CLI/CLI.hpp>

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

namespace tessera::cli {

/// Registers the scene argument (a file, several files, or a '#' pattern), --frames and --frame-order (the
/// protocol's frame order names) on `command`; `what` says where --frame-order applies.
void add_sequence_flags(CLI::App* command, std::vector<std::string>& scenes, std::string& frames,
                        std::string& frame_order, const std::string& what);

/// One frame of a sequence: its number and its scene file.
struct FrameFile {
  int64_t number = 0;            ///< Frame number.
  std::filesystem::path scene;   ///< Its scene file.
};

/// Parses a frame range such as "1-240", "1-240x2" or "1,5,10-20" (each part a number or FIRST-LAST with an optional
/// xSTEP), in the order given; throws std::invalid_argument with a sentence for malformed or empty parts.
std::vector<int64_t> parse_frame_range(const std::string& range);

/// True when `text` holds a run of '#' (a frame pattern).
bool is_frame_pattern(const std::string& text);

/// The frames a command line names: one pattern with a run of '#' and a `range` ("frame_####.json" with "1-240"), or
/// several scene files (a shell glob's expansion), each frame numbered by the last run of digits in its file name.
/// One file without a range is no sequence (returns nothing). Frames come back sorted by number. Throws
/// std::invalid_argument with a sentence naming the frame or file: a range with several files or without a pattern, a
/// pattern without a range, duplicate numbers, a file name without digits, a frame file that does not exist.
std::vector<FrameFile> expand_frames(const std::vector<std::string>& inputs, const std::string& range);

/// `pattern` with its last run of '#' replaced by `number`, zero-padded to the run's length. Without '#', the
/// pattern itself when `frames` is 1; throws std::invalid_argument when several frames would share one file.
std::filesystem::path frame_output(const std::string& pattern, int64_t number, size_t frames);

}  // namespace tessera::cli
