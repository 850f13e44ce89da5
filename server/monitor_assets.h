// The web monitor's static files (server/monitor/), compiled into the binary by cmake/embed_files.cmake.
#pragma once

#include <span>
#include <string_view>

namespace tessera::server {

/// One embedded file.
struct EmbeddedFile {
  std::string_view path;   ///< Path relative to server/monitor/, e.g. "app.js".
  std::string_view bytes;  ///< Its contents.
  std::string_view etag;   ///< A quoted HTTP entity tag derived from its SHA-256.
};

/// Every file of server/monitor/.
std::span<const EmbeddedFile> monitor_assets();

}  // namespace tessera::server
