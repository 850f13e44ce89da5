// Finding the movie step's ffmpeg: a name on a search path as a shell finds it, a path as it is, and nothing for a
// file that is missing or not executable.
#include "server/steps/tool_path.h"

#include "core/util/file_io.h"

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>

namespace tessera::server {
namespace {

namespace fs = std::filesystem;

TEST(ToolPath, ANameIsFoundInTheFirstDirectoryHoldingItAsAnExecutableFile) {
  const fs::path dir = fs::temp_directory_path() / ("tessera-tool-test-" + random_hex(6));
  for (const char* d : {"a", "b", "c"}) fs::create_directories(dir / d);
  std::ofstream(dir / "a" / "enc") << "not executable\n";
  std::ofstream(dir / "c" / "enc") << "#!/bin/sh\n";
  fs::permissions(dir / "c" / "enc", fs::perms::owner_all);
  fs::create_directory(dir / "b" / "enc");  // a directory of that name is no tool
  const std::string path = "relative:" + (dir / "a").string() + "::" + (dir / "b").string() + ":" + (dir / "c").string();
  EXPECT_EQ(find_tool("enc", path), dir / "c" / "enc");
  EXPECT_EQ(find_tool("enc", (dir / "a").string()), std::nullopt);  // not executable
  EXPECT_EQ(find_tool("missing", path), std::nullopt);
  EXPECT_EQ(find_tool("", path), std::nullopt);
  // A path is taken as it is, whatever the search path.
  EXPECT_EQ(find_tool((dir / "c" / "enc").string(), ""), dir / "c" / "enc");
  EXPECT_EQ(find_tool((dir / "a" / "enc").string(), path), std::nullopt);
  EXPECT_EQ(find_tool((dir / "b" / "enc").string(), path), std::nullopt);
  fs::remove_all(dir);
}

}  // namespace
}  // namespace tessera::server
