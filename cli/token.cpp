#include "cli/token.h"

#include "server/auth.h"

#include <spdlog/spdlog.h>

#include <sys/stat.h>

#include <cerrno>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <stdexcept>

namespace tessera::cli {

namespace {

std::string trim(const std::string& s) {
  const size_t b = s.find_first_not_of(" \t\r\n");
  if (b == std::string::npos) return "";
  return s.substr(b, s.find_last_not_of(" \t\r\n") - b + 1);
}

}  // namespace

std::string load_token(const std::string& file, const char* env_var) {
  std::string token, source;
  if (!file.empty()) {
    std::ifstream in(file);
    if (!in) throw std::runtime_error("cannot read token file " + file + ": " + std::strerror(errno));
    std::getline(in, token);
    token = trim(token);
    source = "token file " + file;
    struct stat st {};
    if (::stat(file.c_str(), &st) == 0 && (st.st_mode & (S_IRWXG | S_IRWXO)) != 0)
      spdlog::warn("{} can be read by other users; chmod 600 it", source);
  } else if (const char* v = std::getenv(env_var); v != nullptr) {
    token = trim(v);
    source = std::string("environment variable ") + env_var;
  } else {
    return "";
  }
  if (token.empty()) throw std::runtime_error(source + " holds no token");
  if (const std::string problem = server::token_problem(token); !problem.empty())
    throw std::runtime_error(source + ": " + problem);
  return token;
}

}  // namespace tessera::cli
