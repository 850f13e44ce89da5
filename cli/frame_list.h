// The frames of a sequence as a command line names them: which scene file each frame number has, and where each
// frame's output goes (`render shot/frame_*.json -o out/frame_####.exr`,
// `render shot/frame_####.json --frames 1-240 -o out/frame_####.exr`).
#pragma once

#include <CLI/CLI.hpp>

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

namespace tessera::cli {

/// CLI11's check of a file argument that may also be a frame pattern: a file that exists, or (checked when the command
/// runs) a pattern with '#' or a shell glob that matched nothing.
CLI::Validator file_or_pattern();

/// Registers the scene argument (a file; several files, one per frame; or a '#' pattern), --frames and --frame-order
/// (the protocol's frame order names) on `command`; `where` says where --frame-order applies ("" or "With ...: ").
void add_sequence_flags(CLI::App* command, std::vector<std::string>& scenes, std::string& frames,
                        std::string& frame_order, const std::string& where);

/// One frame of a sequence: its number and its scene file.
struct FrameFile {
  int64_t number = 0;           ///< Frame number (never negative).
  std::filesystem::path scene;  ///< Its scene file.
};

/// Most frames one range may name (a typo such as 1-10000000000 is refused instead of filling memory).
inline constexpr size_t kMaxFrames = 1000000;

/// The frames a command line names: either one or more scene files (`a.json b.json`, or a shell glob's expansion; each
/// frame's number is the last run of digits in its file name without the extension, and files without digits are
/// refused when there are several), or one pattern with a run of '#' and `range` ("1-240", "1-240x2",
/// "1,5,10-20", a step after 'x'). Throws std::invalid_argument with a sentence naming the offending frame or file: a
/// pattern without '#' with a range, a range given with several files, a range that is empty or malformed, duplicate
/// frame numbers, a missing frame file ("frame 17: shot/frame_0017.json does not exist"), a glob that matched nothing,
/// negative numbers. Frames come back sorted by number.
std::vector<FrameFile> expand_frames(const std::vector<std::string>& inputs, const std::string& range);

/// The output path of frame `number`: the last run of '#' in `pattern` replaced by the number zero-padded to the run's
/// length (more digits when it does not fit). A pattern without '#' is returned as it is for a single frame, and
/// refused (std::invalid_argument) when `frames` > 1; a negative number is refused too.
std::filesystem::path frame_output(const std::string& pattern, int64_t number, size_t frames);

/// Parses a range such as "1-240x2,300": comma-separated items, each a frame number N, a range N-M (M >= N) or a
/// range with a step N-MxS (N, N+S, ... up to M). Returns the numbers in ascending order. Throws
/// std::invalid_argument with a sentence for an empty or malformed range or item, a negative number, a step of 0, a
/// frame named twice, or more than kMaxFrames frames.
std::vector<int64_t> parse_frame_range(const std::string& range);

}  // namespace tessera::cli
