// A bound on how often one kind of log line is written: a flood of the same event (refused tokens, say) costs a few
// lines a period and one count of what was left out, not a line per event.
#pragma once

#include <chrono>
#include <cstdint>
#include <mutex>
#include <string>
#include <string_view>

namespace tessera::server {

/// Lets at most `lines` log lines through per `period`. Thread-safe.
class LogLimit {
 public:
  /// At most `lines` lines per `period`.
  LogLimit(int lines, std::chrono::steady_clock::duration period) : lines_(lines), period_(period) {}

  /// What a line allowed after `left_out` refused ones appends: " (N more WHAT not logged before this one)", or
  /// nothing when none was left out.
  static std::string left_out_note(uint64_t left_out, std::string_view what) {
    if (left_out == 0) return {};
    return " (" + std::to_string(left_out) + " more " + std::string(what) + " not logged before this one)";
  }

  /// True when a line may be written now; `left_out` is then set to the lines refused since the last one allowed
  /// (to be said in it), and is untouched otherwise.
  bool allow(uint64_t& left_out, std::chrono::steady_clock::time_point now = std::chrono::steady_clock::now()) {
    std::lock_guard lock(mu_);
    if (now - window_start_ >= period_) {
      window_start_ = now;
      used_ = 0;
    }
    if (used_ >= lines_) {
      ++refused_;
      return false;
    }
    ++used_;
    left_out = refused_;
    refused_ = 0;
    return true;
  }

 private:
  const int lines_;
  const std::chrono::steady_clock::duration period_;
  std::mutex mu_;
  std::chrono::steady_clock::time_point window_start_{};
  int used_ = 0;
  uint64_t refused_ = 0;
};

}  // namespace tessera::server
