#include "cli/frame_list.h"

#include "protocol/sequence.h"

#include <algorithm>
#include <charconv>
#include <optional>
#include <stdexcept>
#include <string_view>
#include <system_error>

namespace tessera::cli {

namespace fs = std::filesystem;

namespace {

using std::invalid_argument;

// `s` in double quotes, for messages.
std::string quoted(const std::string& s) { return "\"" + s + "\""; }

bool is_digit(char c) { return c >= '0' && c <= '9'; }

// Characters a shell glob has; an input holding one that names no file is a pattern that matched nothing.
bool has_glob_characters(const std::string& s) { return s.find_first_of("*?[") != std::string::npos; }

// The number written by the digits at the front of `text`, which it removes; nullopt when `text` does not start with
// a digit. Throws for a number beyond int64_t, naming `range`.
std::optional<int64_t> take_number(std::string_view& text, const std::string& range) {
  size_t n = 0;
  while (n < text.size() && is_digit(text[n])) ++n;
  if (n == 0) return std::nullopt;
  int64_t v = 0;
  const auto r = std::from_chars(text.data(), text.data() + n, v);
  if (r.ec != std::errc())
    throw invalid_argument("frame range " + quoted(range) + ": " + std::string(text.substr(0, n)) + " is too large");
  text.remove_prefix(n);
  return v;
}

// Appends the frames of one comma-separated item of `range` to `out`.
void add_item(std::string_view item, const std::string& range, std::vector<int64_t>& out) {
  const std::string prefix = "frame range " + quoted(range) + ": ";
  const std::string whole(item);
  if (item.empty()) throw invalid_argument(prefix + "an item is empty (two commas in a row, or one at an end)");
  const auto malformed = [&] {
    return invalid_argument(prefix + quoted(whole) +
                            " is not a frame number N, a range N-M or a range with a step N-MxS");
  };
  if (item.front() == '-' || item.find("--") != std::string_view::npos || item.find("x-") != std::string_view::npos)
    throw invalid_argument(prefix + "frame numbers and steps are not negative (" + quoted(whole) + ")");
  const std::optional<int64_t> first = take_number(item, range);
  if (!first) throw malformed();
  if (item.empty()) {
    out.push_back(*first);
    return;
  }
  if (item.front() == 'x') throw invalid_argument(prefix + quoted(whole) + ": a step goes with a range (N-MxS)");
  if (item.front() != '-') throw malformed();
  item.remove_prefix(1);
  const std::optional<int64_t> last = take_number(item, range);
  if (!last) throw malformed();
  int64_t step = 1;
  if (!item.empty()) {
    if (item.front() != 'x') throw malformed();
    item.remove_prefix(1);
    const std::optional<int64_t> s = take_number(item, range);
    if (!s || !item.empty()) throw malformed();
    if (*s == 0) throw invalid_argument(prefix + quoted(whole) + ": the step must be at least 1");
    step = *s;
  }
  if (*last < *first) throw invalid_argument(prefix + quoted(whole) + " is empty: it ends before it starts");
  const uint64_t count = uint64_t(*last - *first) / uint64_t(step) + 1;
  if (count > kMaxFrames || out.size() + count > kMaxFrames)
    throw invalid_argument(prefix + "more than " + std::to_string(kMaxFrames) + " frames");
  for (uint64_t i = 0; i < count; ++i) out.push_back(*first + int64_t(i) * step);
}

// The frame number of a scene file given by name: the last run of digits in its file name without the extension.
std::optional<int64_t> number_in_name(const fs::path& file) {
  const std::string stem = file.stem().string();
  size_t end = stem.size();
  while (end > 0 && !is_digit(stem[end - 1])) --end;
  if (end == 0) return std::nullopt;
  size_t begin = end;
  while (begin > 0 && is_digit(stem[begin - 1])) --begin;
  int64_t v = 0;
  const auto r = std::from_chars(stem.data() + begin, stem.data() + end, v);
  if (r.ec != std::errc())
    throw invalid_argument("the frame number in " + quoted(file.string()) + " (" + stem.substr(begin, end - begin) +
                           ") is too large");
  return v;
}

// Throws unless `input`, a scene file named on the command line, is a file.
void check_named_file(const std::string& input) {
  std::error_code ec;
  const fs::file_status st = fs::status(input, ec);
  if (fs::is_regular_file(st)) return;
  if (fs::exists(st)) throw invalid_argument(quoted(input) + " is not a scene file (it is a folder or a device)");
  if (has_glob_characters(input)) throw invalid_argument(quoted(input) + " matches no file");
  if (input.find('#') != std::string::npos)
    throw invalid_argument(quoted(input) + " does not exist; a scene pattern with '#' needs a frame range (--frames)");
  throw invalid_argument(quoted(input) + " does not exist");
}

// Sorts `frames` by number; throws when two have the same number.
void sort_frames(std::vector<FrameFile>& frames) {
  std::sort(frames.begin(), frames.end(), [](const FrameFile& a, const FrameFile& b) { return a.number < b.number; });
  for (size_t i = 1; i < frames.size(); ++i)
    if (frames[i].number == frames[i - 1].number)
      throw invalid_argument("frame " + std::to_string(frames[i].number) + " is named twice: " +
                             frames[i - 1].scene.string() + " and " + frames[i].scene.string());
}

}  // namespace

std::vector<int64_t> parse_frame_range(const std::string& range) {
  if (range.empty()) throw invalid_argument("the frame range is empty (e.g. 1-240, 1-240x2 or 1,5,10-20)");
  std::vector<int64_t> out;
  size_t begin = 0;
  while (true) {
    const size_t comma = range.find(',', begin);
    add_item(std::string_view(range).substr(begin, comma == std::string::npos ? std::string::npos : comma - begin),
             range, out);
    if (comma == std::string::npos) break;
    begin = comma + 1;
  }
  std::sort(out.begin(), out.end());
  const auto twice = std::adjacent_find(out.begin(), out.end());
  if (twice != out.end())
    throw invalid_argument("frame range " + quoted(range) + " names frame " + std::to_string(*twice) + " twice");
  return out;
}

fs::path frame_output(const std::string& pattern, int64_t number, size_t frames) {
  if (number < 0) throw invalid_argument("frame " + std::to_string(number) + ": frame numbers are not negative");
  const size_t last = pattern.rfind('#');
  if (last == std::string::npos) {
    if (frames <= 1) return pattern;
    const fs::path p(pattern);
    const fs::path example = p.parent_path() / (p.stem().string() + "_####" + p.extension().string());
    throw invalid_argument(quoted(pattern) + " has no run of '#' for the frame number, and there are " +
                           std::to_string(frames) + " frames (e.g. " + example.string() + ")");
  }
  size_t first = last;
  while (first > 0 && pattern[first - 1] == '#') --first;
  const size_t width = last - first + 1;
  std::string digits = std::to_string(number);
  if (digits.size() < width) digits.insert(0, width - digits.size(), '0');
  return pattern.substr(0, first) + digits + pattern.substr(last + 1);
}

CLI::Validator file_or_pattern() {
  return CLI::Validator(
      [](std::string& s) { return s.find_first_of("#*?[") != std::string::npos ? std::string() : CLI::ExistingFile(s); },
      "FILE");
}

void add_sequence_flags(CLI::App* c, std::vector<std::string>& scenes, std::string& frames, std::string& frame_order,
                        const std::string& where) {
  c->add_option("scene", scenes,
                "Scene file (course JSON format); several make a sequence, one frame each, numbered by the last run of "
                "digits in their names (e.g. shot/frame_*.json); or one pattern with a run of '#' and --frames")
      ->required()
      ->check(file_or_pattern());
  c->add_option("--frames", frames,
                "The frames of a scene pattern with a run of '#': N, N-M, N-MxSTEP, or a comma-separated list of those "
                "(e.g. 1-240, 1-240x2, 1,5,10-20)");
  std::vector<std::string> orders(std::begin(protocol::kFrameOrderNames), std::end(protocol::kFrameOrderNames));
  c->add_option("--frame-order", frame_order,
                where + "in_order: frames finish one after another; any: each worker keeps to a frame of its own")
      ->check(CLI::IsMember(orders))->capture_default_str();
}

std::vector<FrameFile> expand_frames(const std::vector<std::string>& inputs, const std::string& range) {
  if (inputs.empty()) throw invalid_argument("no scene file given");
  std::vector<FrameFile> frames;
  if (!range.empty()) {
    if (inputs.size() > 1)
      throw invalid_argument("a frame range (" + quoted(range) + ") goes with one scene pattern such as "
                             "shot/frame_####.json, not with " + std::to_string(inputs.size()) + " scene files");
    const std::string& pattern = inputs.front();
    if (pattern.find('#') == std::string::npos)
      throw invalid_argument("frame range " + quoted(range) + " needs a scene pattern with a run of '#' for the frame "
                             "number (e.g. shot/frame_####.json); " + quoted(pattern) + " has none");
    const std::vector<int64_t> numbers = parse_frame_range(range);
    std::vector<FrameFile> missing;
    for (const int64_t n : numbers) {
      FrameFile f{n, frame_output(pattern, n, numbers.size())};
      std::error_code ec;
      if (fs::is_regular_file(f.scene, ec)) frames.push_back(std::move(f));
      else missing.push_back(std::move(f));
    }
    if (!missing.empty()) {
      const FrameFile& m = missing.front();
      std::error_code ec;
      std::string what =
          fs::exists(m.scene, ec) ? " is not a scene file (it is a folder or a device)" : " does not exist";
      if (missing.size() > 1)
        what += " (" + std::to_string(missing.size()) + " of the " + std::to_string(numbers.size()) +
                " frames are missing)";
      throw invalid_argument("frame " + std::to_string(m.number) + ": " + m.scene.string() + what);
    }
    return frames;
  }
  for (const std::string& input : inputs) {
    check_named_file(input);
    const std::optional<int64_t> number = number_in_name(input);
    if (!number && inputs.size() > 1)
      throw invalid_argument(quoted(input) + " has no frame number: with several scene files, the last run of digits "
                             "in each file's name is its frame number (e.g. shot/frame_0017.json)");
    frames.push_back({number.value_or(0), input});
  }
  sort_frames(frames);
  return frames;
}

}  // namespace tessera::cli
