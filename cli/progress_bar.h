// The progress display shared by `tessera render` (local or farm), `submit` and `jobs wait`, and the time and rate texts
// the listings share with it.
#pragma once

#include "core/render/render.h"

#include <cstdio>
#include <string>

#include <unistd.h>

namespace tessera::cli {

/// "12.3s", "4m05s" or "1h02m".
inline std::string format_duration(double s) {
  char buf[64];
  if (s < 60) std::snprintf(buf, sizeof buf, "%.1fs", s);
  else if (s < 3600) std::snprintf(buf, sizeof buf, "%dm%02ds", int(s) / 60, int(s) % 60);
  else std::snprintf(buf, sizeof buf, "%dh%02dm", int(s) / 3600, (int(s) / 60) % 60);
  return buf;
}

/// Rays per second in millions ("12.3"), or "-" when there are no rays or no time to divide by.
inline std::string format_mrays(uint64_t rays, double seconds) {
  if (rays == 0 || !(seconds > 0)) return "-";
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.1f", double(rays) / seconds * 1e-6);
  return buf;
}

/// A one-line progress bar on a terminal; on a pipe, a line at every 10% instead. Ray rates are shown when known.
/// The ETA is shown once a tile is done ("ETA -" before), and the last line gives the elapsed time instead.
class ProgressBar {
 public:
  /// A bar that prints nothing unless enabled.
  explicit ProgressBar(bool enabled) : enabled_(enabled), tty_(isatty(STDERR_FILENO)) {}
  /// Text shown before the tile counts from the next update on (a sequence's "3/24 frames, ").
  void set_prefix(std::string prefix) { prefix_ = std::move(prefix); }
  /// Shows p (tiles done of total, rays and elapsed time).
  void update(const RenderProgress& p) {
    if (!enabled_ || p.tiles_total == 0) return;
    const double frac = double(p.tiles_done) / p.tiles_total;
    const bool done = p.tiles_done == p.tiles_total;
    const std::string rate = p.rays > 0 && p.seconds > 0 ? "  " + format_mrays(p.rays, p.seconds) + " Mrays/s" : "";
    const std::string time = done       ? "in " + format_duration(p.seconds)
                             : frac > 0 ? "ETA " + format_duration(p.seconds * (1 - frac) / frac)
                                        : std::string("ETA -");
    if (tty_) {
      constexpr int kWidth = 30;
      const int filled = int(frac * kWidth);
      std::fprintf(stderr, "\r[%.*s%*s] %s%d/%d tiles%s  %s   ", filled, "##############################",
                   kWidth - filled, "", prefix_.c_str(), p.tiles_done, p.tiles_total, rate.c_str(), time.c_str());
      if (done) std::fputc('\n', stderr);
      return;
    }
    // On a pipe: a line per decile, and the last one again only if it has news (the rate, known at the end).
    char line[160];
    std::snprintf(line, sizeof line, "%3d%%  %s%d/%d tiles%s", int(frac * 100), prefix_.c_str(), p.tiles_done,
                  p.tiles_total, rate.c_str());
    if (int(frac * 10) > last_decile_ || (done && line != last_line_)) {
      last_decile_ = int(frac * 10);
      last_line_ = line;
      std::fprintf(stderr, "%s  %s\n", line, time.c_str());
    }
  }

 private:
  bool enabled_, tty_;
  int last_decile_ = -1;
  std::string last_line_;  // the last line printed on a pipe, without its time
  std::string prefix_;     // set_prefix
};

}  // namespace tessera::cli
