// The commands' check, before their long work, that the file they will write can be created.
#pragma once

#include "core/util/output_file.h"

#include <spdlog/spdlog.h>

#include <exception>
#include <filesystem>
#include <string>

namespace tessera::cli {

/// Whether a file can be created at `path` (check_output_writable); when not, logs why. The commands then exit 2
/// before any work is done.
inline bool output_writable(const std::filesystem::path& path, const std::string& what = "output") {
  try {
    check_output_writable(path, what);
    return true;
  } catch (const std::exception& e) {
    spdlog::error("{}", e.what());
    return false;
  }
}

}  // namespace tessera::cli
