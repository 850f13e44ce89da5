// Fuzz-target helper: a private scratch folder per fuzzing process, for targets whose code under test reads files.
#pragma once

#include <filesystem>
#include <string>
#include <unistd.h>

namespace tessera::fuzz {

/// A folder tessera-fuzz-LABEL-PID under the system temporary folder, created at construction and removed (with its
/// contents) when the process exits normally; hold it in a function-local static.
struct ScratchDir {
  std::filesystem::path path;  ///< The folder.
  /// Creates the folder for this process.
  explicit ScratchDir(const std::string& label)
      : path(std::filesystem::temp_directory_path() / ("tessera-fuzz-" + label + "-" + std::to_string(::getpid()))) {
    std::filesystem::create_directories(path);
  }
  ~ScratchDir() {
    std::error_code ec;
    std::filesystem::remove_all(path, ec);
  }
  ScratchDir(const ScratchDir&) = delete;
  ScratchDir& operator=(const ScratchDir&) = delete;
};

}  // namespace tessera::fuzz
