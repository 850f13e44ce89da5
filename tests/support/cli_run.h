// Test-only: what running the `tessera` binary gave, for the command-line tests.
#pragma once

#include <string>

namespace tessera::testing {

/// The outcome of one run of the binary.
struct CliRun {
  int exit_code;    ///< The process's exit status (-1 when it did not exit normally).
  std::string err;  ///< What it wrote to stderr (and, where a test sends it there, stdout).
};

}  // namespace tessera::testing
