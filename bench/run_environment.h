// The facts every benchmark's result file records about where it ran: CPU, commit, load average.
#pragma once

#include <cstdio>
#include <fstream>
#include <string>

namespace tessera::bench {

/// The first line a shell command prints, without its line ending (empty when it cannot run or prints nothing).
inline std::string first_line_of(const std::string& cmd) {
  FILE* p = ::popen(cmd.c_str(), "r");
  if (!p) return {};
  char buf[512];
  std::string out;
  if (std::fgets(buf, sizeof buf, p)) out = buf;
  ::pclose(p);
  while (!out.empty() && (out.back() == '\n' || out.back() == '\r')) out.pop_back();
  return out;
}

/// The CPU's model name from /proc/cpuinfo, or "unknown".
inline std::string cpu_model() {
  std::ifstream in("/proc/cpuinfo");
  std::string line;
  while (std::getline(in, line)) {
    if (line.rfind("model name", 0) != 0) continue;
    const size_t colon = line.find(':');
    if (colon == std::string::npos) continue;
    const size_t b = line.find_first_not_of(" \t", colon + 1);
    return b == std::string::npos ? std::string() : line.substr(b);
  }
  return "unknown";
}

/// The commit of the source tree at source_dir, asked from git at run time so it is current, and whether tracked
/// files differ from it; configure_commit (the commit when the build was configured) when git cannot answer.
inline std::string commit_description(const std::string& source_dir, const std::string& configure_commit) {
  const std::string head = first_line_of("git -C '" + source_dir + "' rev-parse --short HEAD 2>/dev/null");
  if (head.empty()) return configure_commit + " (from configure time; git unavailable)";
  const std::string dirty =
      first_line_of("git -C '" + source_dir + "' status --porcelain --untracked-files=no 2>/dev/null");
  return head + (dirty.empty() ? " (clean tracked tree)" : " (tracked files modified: -dirty)");
}

/// The first three fields of /proc/loadavg (1, 5 and 15 minutes), or "unknown".
inline std::string load_average() {
  std::ifstream in("/proc/loadavg");
  std::string a, b, c;
  if (!(in >> a >> b >> c)) return "unknown";
  return a + " " + b + " " + c;
}

}  // namespace tessera::bench
