#include "protocol/tags.h"

#include "protocol/errors.h"

#include <algorithm>

namespace tessera::protocol {

std::string tag_problem(std::string_view tag) {
  if (tag.empty()) return "a tag must not be empty";
  if (tag.size() > 64) return "a tag has at most 64 characters";
  for (char c : tag)
    if (!((c >= 'a' && c <= 'z') || (c >= '0' && c <= '9') || c == '-' || c == '_' || c == '.'))
      return "tag '" + std::string(tag) + "' may contain only a-z, 0-9, '-', '_' and '.'";
  return "";
}

std::vector<std::string> checked_tags(std::vector<std::string> tags, std::string_view field) {
  for (const std::string& t : tags)
    if (std::string p = tag_problem(t); !p.empty()) throw ProtocolError("'" + std::string(field) + "': " + p);
  std::sort(tags.begin(), tags.end());
  tags.erase(std::unique(tags.begin(), tags.end()), tags.end());
  if (tags.size() > kMaxTags)
    throw ProtocolError("'" + std::string(field) + "' has " + std::to_string(tags.size()) + " tags; at most " +
                        std::to_string(kMaxTags) + " are allowed");
  return tags;
}

std::vector<std::string> parse_tag_list(std::string_view text, std::string_view field) {
  std::vector<std::string> out;
  if (text.empty()) return out;
  size_t i = 0;
  while (true) {
    const size_t j = text.find(',', i);
    out.emplace_back(text.substr(i, j == std::string_view::npos ? std::string_view::npos : j - i));
    if (j == std::string_view::npos) break;
    i = j + 1;
  }
  return checked_tags(std::move(out), field);
}

bool has_tags(const std::vector<std::string>& have, const std::vector<std::string>& need) {
  return std::includes(have.begin(), have.end(), need.begin(), need.end());
}

std::string tag_text(const std::vector<std::string>& tags) {
  std::string out;
  for (const std::string& t : tags) out += (out.empty() ? "" : ", ") + t;
  return out;
}

}  // namespace tessera::protocol
