// remove_tree: a tree of files and nested folders goes whole, with the count of what it removed; symbolic links are
// removed, not followed (what they point at stays); a missing path is no error; a file that is not a folder goes
// alone; a folder it may not empty is reported, with the rest left in place.
#include "core/util/remove_tree.h"
#include "tests/support/test_files.h"

#include <gtest/gtest.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <string>

namespace tessera {
namespace remove_tree_test {  // named: the test files share translation units in a unity build

namespace fs = std::filesystem;

// A fresh folder per test (testing::TempDirTest); a tree a test locked is unlocked before it goes.
class RemoveTree : public testing::TempDirTest {
 protected:
  void TearDown() override {
    std::error_code ec;
    fs::permissions(dir_ / "tree" / "locked", fs::perms::owner_all, ec);
    TempDirTest::TearDown();
  }
  static void write(const fs::path& p, const std::string& bytes) { std::ofstream(p, std::ios::binary) << bytes; }
};

TEST_F(RemoveTree, RemovesATreeAndCountsItsEntries) {
  const fs::path tree = dir_ / "tree";
  for (int a = 0; a < 6; ++a)
    for (int b = 0; b < 3; ++b) {
      const fs::path d = tree / ("a" + std::to_string(a)) / ("b" + std::to_string(b));
      fs::create_directories(d);
      write(d / "file", std::string(5000, char('a' + b)));
    }
  fs::create_directories(tree / "empty" / "deeper" / "deepest");
  write(tree / "top", "x");
  // 6 + 18 folders with 18 files, 3 empty folders, 1 file, and the tree itself
  std::error_code ec;
  EXPECT_EQ(remove_tree(tree, ec), 6u + 18u + 18u + 3u + 1u + 1u);
  EXPECT_FALSE(ec) << ec.message();
  EXPECT_FALSE(fs::exists(tree));
  EXPECT_TRUE(fs::exists(dir_));
}

TEST_F(RemoveTree, RemovesLinksWithoutFollowingThem) {
  const fs::path outside = dir_ / "outside";
  fs::create_directories(outside / "inner");
  write(outside / "inner" / "kept", "kept");
  write(outside / "file", "kept too");
  const fs::path tree = dir_ / "tree";
  fs::create_directories(tree / "sub");
  fs::create_directory_symlink(outside, tree / "sub" / "to_folder");
  fs::create_symlink(outside / "file", tree / "to_file");
  std::error_code ec;
  EXPECT_EQ(remove_tree(tree, ec), 4u);
  EXPECT_FALSE(ec) << ec.message();
  EXPECT_FALSE(fs::exists(tree));
  EXPECT_TRUE(fs::exists(outside / "inner" / "kept"));
  EXPECT_TRUE(fs::exists(outside / "file"));
}

TEST_F(RemoveTree, MissingPathIsNoErrorAndAFileGoesAlone) {
  std::error_code ec;
  EXPECT_EQ(remove_tree(dir_ / "nothing", ec), 0u);
  EXPECT_FALSE(ec) << ec.message();
  write(dir_ / "single", "x");
  EXPECT_EQ(remove_tree(dir_ / "single", ec), 1u);
  EXPECT_FALSE(ec) << ec.message();
  EXPECT_FALSE(fs::exists(dir_ / "single"));
}

// Permissions do not bind root, so the removal runs in a child process, as the unprivileged user `nobody` (65534)
// when the test runs as root (the tree is handed to that user first); the child's exit status says whether
// remove_tree reported an error.
TEST_F(RemoveTree, ReportsWhatItCannotRemove) {
  const fs::path tree = dir_ / "tree";
  fs::create_directories(tree / "locked");
  write(tree / "locked" / "stays", "x");
  write(tree / "goes", "x");
  const bool root = ::geteuid() == 0;
  constexpr uid_t kNobody = 65534;
  if (root) {
    ASSERT_EQ(::chown(dir_.c_str(), kNobody, kNobody), 0);
    for (const fs::directory_entry& e : fs::recursive_directory_iterator(dir_))
      ASSERT_EQ(::lchown(e.path().c_str(), kNobody, kNobody), 0) << e.path();
  }
  fs::permissions(tree / "locked", fs::perms::owner_read | fs::perms::owner_exec);
  const pid_t child = ::fork();
  ASSERT_GE(child, 0);
  if (child == 0) {
    if (root && (::setgid(kNobody) != 0 || ::setuid(kNobody) != 0)) ::_exit(3);
    std::error_code ec;
    remove_tree(tree, ec);
    ::_exit(ec ? 0 : 2);
  }
  int status = 0;
  ASSERT_EQ(::waitpid(child, &status, 0), child);
  ASSERT_TRUE(WIFEXITED(status));
  EXPECT_EQ(WEXITSTATUS(status), 0) << "2: no error reported; 3: could not become nobody";
  EXPECT_TRUE(fs::exists(tree / "locked" / "stays"));
  EXPECT_FALSE(fs::exists(tree / "goes"));
}

}  // namespace remove_tree_test
}  // namespace tessera
