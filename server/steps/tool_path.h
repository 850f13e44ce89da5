// Finding an external tool the coordinator runs (the movie step's ffmpeg): a name is looked up in the directories of
// a search path as a shell would, a path is taken as it is. Nothing is run here.
#pragma once

#include <filesystem>
#include <optional>
#include <string>
#include <string_view>

namespace tessera::server {

/// The executable file `tool` names: with a '/', that path when it is an executable regular file; else the first
/// executable regular file of that name in the ':'-separated `search_path` (empty entries and relative directories are
/// skipped). Nothing when there is none.
std::optional<std::filesystem::path> find_tool(const std::string& tool, std::string_view search_path);

/// The coordinator's own search path (its PATH), "" when it has none.
std::string process_search_path();

}  // namespace tessera::server
