#include "core/util/output_file.h"

#include <cerrno>
#include <cstdlib>
#include <stdexcept>
#include <system_error>
#include <unistd.h>

namespace tessera {

void check_output_writable(const std::filesystem::path& path, const std::string& what) {
  namespace fs = std::filesystem;
  const auto fail = [&](const std::string& why) {
    throw std::runtime_error("cannot write the " + what + " \"" + path.string() + "\": " + why);
  };
  if (path.empty()) fail("empty path");
  std::error_code ec;
  if (fs::is_directory(path, ec)) fail("it is a folder");
  const fs::path dir = path.has_parent_path() ? path.parent_path() : fs::path(".");
  if (!fs::exists(dir, ec)) fail("the folder \"" + dir.string() + "\" does not exist");
  if (!fs::is_directory(dir, ec)) fail("\"" + dir.string() + "\" is not a folder");
  // Built by appending: GCC 12 at -O3 warns (-Wrestrict, falsely) on "literal" + std::string chains.
  std::string name = ".";
  name += path.filename().string();
  name += ".probe-XXXXXX";
  std::string probe = (dir / name).string();
  const int fd = ::mkstemp(probe.data());
  if (fd < 0) fail("cannot create files in \"" + dir.string() + "\": " + std::error_code(errno, std::generic_category()).message());
  ::close(fd);
  ::unlink(probe.c_str());
}

}  // namespace tessera
