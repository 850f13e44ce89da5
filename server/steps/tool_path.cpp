#include "server/steps/tool_path.h"

#include <unistd.h>

#include <cstdlib>

namespace fs = std::filesystem;

namespace tessera::server {

namespace {

bool executable_file(const fs::path& p) {
  std::error_code ec;
  return fs::is_regular_file(p, ec) && ::access(p.c_str(), X_OK) == 0;
}

}  // namespace

std::optional<fs::path> find_tool(const std::string& tool, std::string_view search_path) {
  if (tool.empty()) return std::nullopt;
  if (tool.find('/') != std::string::npos) {
    if (executable_file(tool)) return fs::path(tool);
    return std::nullopt;
  }
  while (true) {
    const size_t colon = search_path.find(':');
    const std::string_view dir = search_path.substr(0, colon);
    if (!dir.empty() && dir.front() == '/') {
      fs::path candidate = fs::path(dir) / tool;
      if (executable_file(candidate)) return candidate;
    }
    if (colon == std::string_view::npos) return std::nullopt;
    search_path.remove_prefix(colon + 1);
  }
}

std::string process_search_path() {
  const char* path = std::getenv("PATH");
  return path ? path : "";
}

}  // namespace tessera::server
