#include "cli/farm_log.h"

#include <spdlog/details/os.h>
#include <spdlog/sinks/base_sink.h>
#include <spdlog/sinks/basic_file_sink.h>
#include <spdlog/spdlog.h>

#include <algorithm>
#include <mutex>
#include <utility>
#include <vector>

namespace tessera::cli {

namespace {

// Sends a message to the terminal's sinks when the thread `own` wrote it at `own_level` or above, else to the file.
class ThreadSplitSink : public spdlog::sinks::base_sink<std::mutex> {
 public:
  ThreadSplitSink(size_t own, spdlog::level::level_enum own_level, std::vector<spdlog::sink_ptr> terminal,
                  spdlog::sink_ptr file)
      : own_(own), own_level_(own_level), terminal_(std::move(terminal)), file_(std::move(file)) {}

 protected:
  void sink_it_(const spdlog::details::log_msg& msg) override {
    if (msg.thread_id != own_) return file_->log(msg);
    if (msg.level < own_level_) return;
    for (const auto& s : terminal_)
      if (s->should_log(msg.level)) s->log(msg);
  }
  void flush_() override {
    for (const auto& s : terminal_) s->flush();
    file_->flush();
  }

 private:
  const size_t own_;
  const spdlog::level::level_enum own_level_;
  const std::vector<spdlog::sink_ptr> terminal_;
  const spdlog::sink_ptr file_;
};

}  // namespace

FarmLog::FarmLog(const std::filesystem::path& file) : previous_(spdlog::default_logger()) {
  auto to_file = std::make_shared<spdlog::sinks::basic_file_sink_mt>(file.string());
  to_file->set_pattern("[%Y-%m-%d %H:%M:%S.%e] [%l] %v");  // a coordinator process's lines (no logger name)
  auto split = std::make_shared<ThreadSplitSink>(spdlog::details::os::thread_id(), previous_->level(), previous_->sinks(),
                                                 std::move(to_file));
  auto logger = std::make_shared<spdlog::logger>(previous_->name(), std::move(split));
  // The coordinator's informational lines reach its file whatever the terminal shows, each at once (as a process's
  // unbuffered stderr would), so that the file can be read while it runs.
  logger->set_level(std::min(previous_->level(), spdlog::level::info));
  logger->flush_on(spdlog::level::trace);
  spdlog::set_default_logger(std::move(logger));
}

FarmLog::~FarmLog() { spdlog::set_default_logger(previous_); }

}  // namespace tessera::cli
