#include "core/scene/obj_limits.h"

namespace tessera {

namespace {

bool blank(char c) { return c == ' ' || c == '\t'; }

// Corners of a face line's rest (after "f "): runs of characters other than blanks and \r.
uint64_t corners(std::string_view rest) {
  uint64_t n = 0;
  bool in_word = false;
  for (const char c : rest) {
    const bool separator = blank(c) || c == '\r';
    if (!separator && !in_word) ++n;
    in_word = !separator;
  }
  return n;
}

}  // namespace

ObjCounts count_obj(std::string_view text) {
  ObjCounts n;
  size_t at = 0;
  while (at < text.size()) {
    size_t end = text.find_first_of("\n\r", at);
    if (end == std::string_view::npos) end = text.size();
    std::string_view line = text.substr(at, end - at);
    at = end + 1;
    while (!line.empty() && blank(line.front())) line.remove_prefix(1);
    if (line.size() < 2) continue;
    if (line[0] == 'f' && blank(line[1])) {
      const uint64_t k = corners(line.substr(2));
      if (k >= 3) n.triangles += k - 2;
    } else if (line[0] == 'v' && blank(line[1])) {
      ++n.positions;
    } else if (line.size() >= 3 && line[0] == 'v' && blank(line[2])) {
      if (line[1] == 'n') ++n.normals;
      else if (line[1] == 't') ++n.texcoords;
    }
  }
  return n;
}

}  // namespace tessera
