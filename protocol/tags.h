// Worker tags and job requirements (docs/operations.md, "Pools and requirements"): a job is leased only to workers
// whose tags include every tag it requires.
#pragma once

#include <string>
#include <string_view>
#include <vector>

namespace tessera::protocol {

/// Most tags a worker announces or a job requires.
inline constexpr size_t kMaxTags = 32;

/// The problem with a tag (1 to 64 of a-z, 0-9, '-', '_', '.'), or "" when it is fine.
std::string tag_problem(std::string_view tag);
/// Checks a list of tags; throws ProtocolError naming `field` and the first bad tag; returns them sorted, without
/// duplicates.
std::vector<std::string> checked_tags(std::vector<std::string> tags, std::string_view field);
/// Splits "gpu,bigmem" into checked tags (as checked_tags); empty text: none.
std::vector<std::string> parse_tag_list(std::string_view text, std::string_view field);
/// True when `have` (sorted) includes every tag of `need` (sorted).
bool has_tags(const std::vector<std::string>& have, const std::vector<std::string>& need);
/// "bigmem, site-a".
std::string tag_text(const std::vector<std::string>& tags);

}  // namespace tessera::protocol
