// Access tokens for the command line: read from a file named by an option or from an environment variable.
#pragma once

#include <string>

namespace tessera::cli {

/// The token in `file` (its first line, surrounding whitespace removed) when `file` is not empty, else the value of
/// the environment variable `env_var`, else "". Throws std::runtime_error naming the file or variable when the token
/// cannot be read or is unusable; warns when the file can be read by other users. Never logs the token.
std::string load_token(const std::string& file, const char* env_var);

}  // namespace tessera::cli
