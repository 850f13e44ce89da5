// The exit statuses of every `tessera` command, one rule for all of them (README, "Exit status"): a script can tell
// a request refused before any work (fix the input, run again) from work that failed once begun.
#pragma once

#include <stdexcept>

namespace tessera::cli {

/// Done as asked.
inline constexpr int kExitOk = 0;
/// Work was begun and failed: a render error, a failed or cancelled job, a coordinator lost during the wait.
inline constexpr int kExitFailed = 1;
/// Refused before any work, nothing written: the command line, the scene, a file to read or to write, a job id or
/// the coordinator's answer to the request (401, 404, 409, 422...).
inline constexpr int kExitRefused = 2;
/// `render --tile-budget N` stopped after N tiles: the partial file is resumed with --resume.
inline constexpr int kExitBudget = 3;
/// SIGINT or SIGTERM: the partial file, or the job left running on the coordinator, is named on stderr.
inline constexpr int kExitInterrupted = 130;

/// An error that means the request was refused before any work: the command exits kExitRefused.
class Refusal : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

}  // namespace tessera::cli
