// Fail points: named places in the coordinator and worker where a test can make the process fail, crash, stop or
// wait (in the manner of FreeBSD's fail(9) and TiKV's fail-rs). They exist only in test builds: without
// TESSERA_FAILPOINTS every macro below expands to nothing, so the release `tessera` contains neither the points'
// names nor the code that reads their settings (tests/release_binary.sh checks its bytes). CMake compiles the files
// that hold fail points a second time with TESSERA_FAILPOINTS into `tessera-failpoints`, a test-only binary.
//
// Settings come from the environment variable TESSERA_FAIL_POINTS, read once at start-up by the test binary only:
//   TESSERA_FAIL_POINTS="NAME=ACTIONS;NAME=ACTIONS..."   ACTIONS = TERM[->TERM...]   TERM = [COUNT*]KIND[(ARG)]
// KIND is one of
//   off        nothing happens;
//   print      logs the hit (for tests that count events);
//   error      throws failpoint::Injected ("injected error at fail point NAME");
//   abort      logs, flushes the log and calls std::abort() (a crash: no destructors, no clean-up);
//   stop       raises SIGSTOP (a frozen machine; SIGCONT resumes);
//   pause      waits until the file ARG exists (forever without ARG), or until the point's cancel check is true;
//   return     hands ARG to the point's handler (what it does is written at the point).
// A term with COUNT applies to that many hits, then the next term takes over; a term without one applies to every
// later hit. "2*off->abort" lets two hits pass and crashes on the third. A name that is not in kNames below, or a
// setting that does not parse, stops the test binary at start-up with a message (exit status 2).
// Every hit of a point that is not off logs "fail point NAME: hit N: WHAT" through spdlog.
#pragma once

#if defined(TESSERA_FAILPOINTS)

#include <spdlog/spdlog.h>

#include <unistd.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <functional>
#include <map>
#include <mutex>
#include <optional>
#include <stdexcept>
#include <string>
#include <string_view>
#include <thread>
#include <vector>

namespace tessera::failpoint {

/// Every fail point: where it is and what it is for (docs/testing.md lists the same).
inline constexpr std::array<std::string_view, 11> kNames = {
    "worker.render",          // worker: after the job's scene is ready, before the tile's render (cancellable pause)
    "worker.render.fail_tiles",  // worker: return(N,M,...) fails the render of the listed tiles (on every worker)
    "worker.upload",          // worker: a rendered tile, before its upload
    "worker.upload.corrupt",  // worker: return(nan|size) uploads a tile with a NaN pixel / one column too few
    "worker.upload.repeat",   // worker: return sends an acknowledged upload once more
    "store.tile_commit",      // coordinator: an upload's transaction is open, its pixels not yet written (no COMMIT)
    "store.sync",             // coordinator: a flush of the log (group commit), before fdatasync; return: it fails (EIO)
    "assembly.paste",         // coordinator: an upload's pixels, before they are pasted into the job's image
    "assembly.write_result",  // coordinator: all tiles done, before the result EXR is written
    "submit.validate",        // coordinator: a job submission, before its scene is loaded and checked
    "webhook.deliver",        // coordinator: a webhook event stored, before an attempt to deliver it
};

/// Whether `name` is a known fail point (checked at compile time by the macros).
constexpr bool known(std::string_view name) {
  return std::find(kNames.begin(), kNames.end(), name) != kNames.end();
}

/// What the error action throws.
struct Injected : std::runtime_error {
  using std::runtime_error::runtime_error;
};

struct Term {
  enum Kind { off, print, error, abort, stop, pause, ret } kind = off;
  int count = -1;  // hits left for this term; -1: every later hit
  std::string arg;
};

// One point's parsed actions and its hit counter.
struct Point {
  std::vector<Term> terms;
  size_t current = 0;
  long hits = 0;
};

inline Term parse_term(std::string_view text, const std::string& where) {
  Term t;
  if (const auto star = text.find('*'); star != std::string_view::npos) {
    const std::string n(text.substr(0, star));
    char* end = nullptr;
    const long v = std::strtol(n.c_str(), &end, 10);
    if (n.empty() || *end != '\0' || v < 0) throw std::invalid_argument(where + ": bad count '" + n + "'");
    t.count = int(v);
    text.remove_prefix(star + 1);
  }
  if (const auto open = text.find('('); open != std::string_view::npos) {
    if (text.back() != ')') throw std::invalid_argument(where + ": missing ')'");
    t.arg = std::string(text.substr(open + 1, text.size() - open - 2));
    text = text.substr(0, open);
  }
  static const std::pair<std::string_view, Term::Kind> kinds[] = {
      {"off", Term::off},   {"print", Term::print}, {"error", Term::error},  {"abort", Term::abort},
      {"stop", Term::stop}, {"pause", Term::pause}, {"return", Term::ret}};
  for (const auto& [word, kind] : kinds)
    if (text == word) {
      t.kind = kind;
      return t;
    }
  throw std::invalid_argument(where + ": unknown action '" + std::string(text) +
                              "' (off, print, error, abort, stop, pause, return)");
}

/// Parses a TESSERA_FAIL_POINTS value; throws std::invalid_argument naming what is wrong.
inline std::map<std::string, Point, std::less<>> parse(std::string_view spec) {
  std::map<std::string, Point, std::less<>> out;
  while (!spec.empty()) {
    const auto semi = spec.find(';');
    const std::string_view item = spec.substr(0, semi);
    spec = semi == std::string_view::npos ? std::string_view{} : spec.substr(semi + 1);
    if (item.empty()) continue;
    const auto eq = item.find('=');
    if (eq == std::string_view::npos) throw std::invalid_argument("'" + std::string(item) + "': expected NAME=ACTIONS");
    const std::string name(item.substr(0, eq));
    if (!known(name)) throw std::invalid_argument("unknown fail point '" + name + "'");
    Point p;
    std::string_view actions = item.substr(eq + 1);
    while (true) {
      const auto arrow = actions.find("->");
      p.terms.push_back(parse_term(actions.substr(0, arrow), name));
      if (arrow == std::string_view::npos) break;
      actions.remove_prefix(arrow + 2);
    }
    out[name] = std::move(p);
  }
  return out;
}

// The settings of this process, read from the environment once.
struct Registry {
  std::mutex mu;
  std::map<std::string, Point, std::less<>> points;

  Registry() {
    const char* spec = std::getenv("TESSERA_FAIL_POINTS");
    try {
      if (spec) points = parse(spec);
    } catch (const std::invalid_argument& e) {
      std::fprintf(stderr, "TESSERA_FAIL_POINTS: %s\n", e.what());
      std::_Exit(2);
    }
  }
  static Registry& get() {
    static Registry r;
    return r;
  }
};

// Settings are checked when the test binary starts, not at the first hit.
inline const bool kSettingsChecked = (Registry::get(), true);

/// Runs the action of `name` for this hit. `cancelled` ends a pause early (a long step that can be interrupted);
/// `handler` receives the argument of a return action.
inline void hit(std::string_view name, const std::function<bool()>& cancelled = {},
                const std::function<void(const std::string&)>& handler = {}) {
  Registry& reg = Registry::get();
  Term term;
  long n = 0;
  {
    std::lock_guard lock(reg.mu);
    const auto it = reg.points.find(name);
    if (it == reg.points.end()) return;
    Point& p = it->second;
    while (p.current < p.terms.size() && p.terms[p.current].count == 0) ++p.current;
    if (p.current == p.terms.size()) return;
    Term& t = p.terms[p.current];
    if (t.count > 0) --t.count;
    term = t;
    n = ++p.hits;
  }
  switch (term.kind) {
    case Term::off: return;
    case Term::print: spdlog::warn("fail point {}: hit {}", name, n); return;
    case Term::error:
      spdlog::warn("fail point {}: hit {}: error", name, n);
      throw Injected("injected error at fail point " + std::string(name));
    case Term::abort:
      spdlog::warn("fail point {}: hit {}: abort", name, n);
      spdlog::default_logger()->flush();
      std::abort();
    case Term::stop:
      spdlog::warn("fail point {}: hit {}: stopping the process (SIGSTOP)", name, n);
      std::raise(SIGSTOP);
      spdlog::warn("fail point {}: continued", name);
      return;
    case Term::pause: {
      spdlog::warn("fail point {}: hit {}: paused until {}", name, n, term.arg.empty() ? "cancelled" : term.arg + " exists");
      std::error_code ec;
      while (!(cancelled && cancelled()) && (term.arg.empty() || !std::filesystem::exists(term.arg, ec)))
        std::this_thread::sleep_for(std::chrono::milliseconds(5));
      spdlog::warn("fail point {}: {}", name, cancelled && cancelled() ? "pause cancelled" : "released");
      return;
    }
    case Term::ret:
      spdlog::warn("fail point {}: hit {}: return({})", name, n, term.arg);
      if (handler) handler(term.arg);
      return;
  }
}

/// True when this process was given a setting for `name` (code that could go past the point checks first).
inline bool is_set(std::string_view name) {
  Registry& reg = Registry::get();
  std::lock_guard lock(reg.mu);
  return reg.points.find(name) != reg.points.end();
}

}  // namespace tessera::failpoint

#define TESSERA_FAIL_POINT_CHECKED_(name, ...)                                          \
  do {                                                                                  \
    static_assert(::tessera::failpoint::known(name), "unknown fail point: " name);      \
    ::tessera::failpoint::hit(name __VA_OPT__(, ) __VA_ARGS__);                         \
  } while (0)
/// A fail point: error, abort, stop, pause (until its file exists), print.
#define TESSERA_FAIL_POINT(name) TESSERA_FAIL_POINT_CHECKED_(name)
/// A fail point in a long step that `cancelled()` can interrupt: a pause ends when it returns true.
#define TESSERA_FAIL_POINT_CANCELLABLE(name, cancelled) TESSERA_FAIL_POINT_CHECKED_(name, cancelled)
/// A fail point whose return(ARG) action calls the handler (the macro's last argument, a callable taking
/// const std::string&) with ARG; the handler's code exists in test builds only.
#define TESSERA_FAIL_POINT_RETURN(name, ...) TESSERA_FAIL_POINT_CHECKED_(name, {}, __VA_ARGS__)
/// True when the test binary was given a setting for the point (false in release builds).
#define TESSERA_FAIL_POINT_SET(name)                                                       \
  ([] {                                                                                    \
    static_assert(::tessera::failpoint::known(name), "unknown fail point: " name);         \
    return ::tessera::failpoint::is_set(name);                                             \
  }())

#else

#define TESSERA_FAIL_POINT(name) ((void)0)
#define TESSERA_FAIL_POINT_CANCELLABLE(name, cancelled) ((void)0)
#define TESSERA_FAIL_POINT_RETURN(name, ...) ((void)0)
#define TESSERA_FAIL_POINT_SET(name) false

#endif
