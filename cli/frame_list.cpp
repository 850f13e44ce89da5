#include "cli/frame_list.h"

#include "protocol/sequence.h"

#include <algorithm>
#include <charconv>
#include <stdexcept>
#include <system_error>

namespace tessera::cli {

namespace fs = std::filesystem;

namespace {

// A whole non-negative number within the protocol's frame numbers, or std::invalid_argument naming `what`.
int64_t frame_number(std::string_view text, const std::string& what) {
  int64_t n = -1;
  const auto [end, ec] = std::from_chars(text.data(), text.data() + text.size(), n);
  if (text.empty() || ec != std::errc() || end != text.data() + text.size() || n < 0 ||
      n > protocol::kMaxFrameNumber)
    throw std::invalid_argument(what + ": '" + std::string(text) + "' is not a frame number (0 to " +
                                std::to_string(protocol::kMaxFrameNumber) + ")");
  return n;
}

// [begin, end) of the last run of `c` in s, or npos.
std::pair<size_t, size_t> last_run(const std::string& s, bool (*is)(char)) {
  size_t end = s.size();
  while (end > 0 && !is(s[end - 1])) --end;
  if (end == 0) return {std::string::npos, std::string::npos};
  size_t begin = end;
  while (begin > 0 && is(s[begin - 1])) --begin;
  return {begin, end};
}

bool is_hash(char c) { return c == '#'; }
bool is_digit(char c) { return c >= '0' && c <= '9'; }

}  // namespace

void add_sequence_flags(CLI::App* c, std::vector<std::string>& scenes, std::string& frames, std::string& frame_order,
                        const std::string& what) {
  c->add_option("scene", scenes,
                "Scene file (course JSON format); several files, or one pattern with a run of '#' and --frames, make "
                "a sequence")
      ->required();
  c->add_option("--frames", frames, "Frame numbers for a '#' scene pattern: 1-240, 1-240x2 (every 2nd), 1,5,10-20");
  std::vector<std::string> orders(std::begin(protocol::kFrameOrderNames), std::end(protocol::kFrameOrderNames));
  c->add_option("--frame-order", frame_order,
                what + "in_order: frames finish one after another; any: each worker keeps to a frame of its own")
      ->check(CLI::IsMember(orders))->capture_default_str();
}

std::vector<int64_t> parse_frame_range(const std::string& range) {
  const std::string what = "--frames '" + range + "'";
  std::vector<int64_t> out;
  size_t i = 0;
  while (i <= range.size()) {
    const size_t comma = std::min(range.find(',', i), range.size());
    const std::string part = range.substr(i, comma - i);
    if (part.empty()) throw std::invalid_argument(what + ": an empty part (write e.g. 1-240, 1-240x2 or 1,5,10-20)");
    const size_t x = part.find('x');
    const std::string span = part.substr(0, x);
    int64_t step = 1;
    if (x != std::string::npos) {
      step = frame_number(part.substr(x + 1), what + " step");
      if (step < 1) throw std::invalid_argument(what + ": a step must be at least 1");
    }
    const size_t dash = span.find('-', 1);
    const int64_t first = frame_number(span.substr(0, dash), what);
    const int64_t last = dash == std::string::npos ? first : frame_number(span.substr(dash + 1), what);
    if (last < first)
      throw std::invalid_argument(what + ": " + span + " runs backwards (write FIRST-LAST with FIRST <= LAST)");
    if (x != std::string::npos && dash == std::string::npos)
      throw std::invalid_argument(what + ": a step applies to a FIRST-LAST span, not to '" + span + "'");
    for (int64_t n = first; n <= last; n += step) {
      out.push_back(n);
      if (out.size() > size_t(protocol::kDefaultMaxJobFrames))
        throw std::invalid_argument(what + ": more than " + std::to_string(protocol::kDefaultMaxJobFrames) + " frames");
    }
    i = comma + 1;
  }
  return out;
}

bool is_frame_pattern(const std::string& text) { return text.find('#') != std::string::npos; }

std::vector<FrameFile> expand_frames(const std::vector<std::string>& inputs, const std::string& range) {
  std::vector<FrameFile> frames;
  if (!range.empty()) {
    if (inputs.size() != 1 || !is_frame_pattern(inputs.front()))
      throw std::invalid_argument("--frames needs one scene pattern with a run of '#' for the frame number (e.g. "
                                  "shot/frame_####.json), not " + std::to_string(inputs.size()) + " file(s)");
    for (const int64_t n : parse_frame_range(range)) frames.push_back({n, frame_output(inputs.front(), n, 2)});
  } else {
    if (inputs.size() == 1 && !is_frame_pattern(inputs.front())) return {};
    if (inputs.size() == 1)
      throw std::invalid_argument("the scene pattern " + inputs.front() + " needs --frames (e.g. --frames 1-240)");
    for (const std::string& in : inputs) {
      if (is_frame_pattern(in))
        throw std::invalid_argument("a scene pattern (" + in + ") cannot be mixed with other scene files");
      const std::string name = fs::path(in).filename().string();
      const auto [b, e] = last_run(name, is_digit);
      if (b == std::string::npos)
        throw std::invalid_argument(in + ": no frame number in the file name (several scene files are numbered by "
                                    "the last digits of their names, e.g. frame_0012.json)");
      frames.push_back({frame_number(name.substr(b, e - b), in), fs::path(in)});
    }
  }
  std::stable_sort(frames.begin(), frames.end(), [](const auto& a, const auto& b) { return a.number < b.number; });
  for (size_t i = 1; i < frames.size(); ++i)
    if (frames[i].number == frames[i - 1].number)
      throw std::invalid_argument("frame " + std::to_string(frames[i].number) + " is named twice (" +
                                  frames[i - 1].scene.string() + ", " + frames[i].scene.string() + ")");
  for (const FrameFile& f : frames) {
    std::error_code ec;
    if (!fs::is_regular_file(f.scene, ec))
      throw std::invalid_argument("frame " + std::to_string(f.number) + ": " + f.scene.string() + " does not exist");
  }
  return frames;
}

fs::path frame_output(const std::string& pattern, int64_t number, size_t frames) {
  const auto [b, e] = last_run(pattern, is_hash);
  if (b == std::string::npos) {
    if (frames <= 1) return pattern;
    throw std::invalid_argument("the output " + pattern + " has no run of '#' for the frame number, and " +
                                std::to_string(frames) + " frames would share it (write e.g. out/frame_####.exr)");
  }
  std::string digits = std::to_string(number);
  if (digits.size() < e - b) digits.insert(0, e - b - digits.size(), '0');
  return pattern.substr(0, b) + digits + pattern.substr(e);
}

}  // namespace tessera::cli
