// The log of a command that runs a private coordinator on threads of its own: the command's thread speaks to the
// terminal as before, the coordinator's threads write to a file, as a coordinator process's log would be.
#pragma once

#include <spdlog/logger.h>

#include <filesystem>
#include <memory>

namespace tessera::cli {

/// While alive, spdlog's default logger sends the messages of the thread that made it to the previous default
/// logger's sinks (the terminal) and every other thread's to `file` (appended); the destructor restores the previous
/// logger. Throws spdlog::spdlog_ex when `file` cannot be opened.
class FarmLog {
 public:
  explicit FarmLog(const std::filesystem::path& file);
  ~FarmLog();
  FarmLog(const FarmLog&) = delete;
  FarmLog& operator=(const FarmLog&) = delete;

 private:
  std::shared_ptr<spdlog::logger> previous_;
};

}  // namespace tessera::cli
