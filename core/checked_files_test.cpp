// CheckedFiles: an entry is found while its path names the same file with the same size (touching it does not
// matter), and the earliest recorded files are forgotten beyond the capacity.
#include "core/checked_files.h"

#include "core/test_files.h"

#include <gtest/gtest.h>

#include <chrono>

namespace tessera {
namespace {

namespace fs = std::filesystem;

class CheckedFilesTest : public testing::TempDirTest {};

TEST_F(CheckedFilesTest, FoundWhileTheFileIsUnchanged) {
  write("a.bin", "12345");
  CheckedFiles c;
  EXPECT_FALSE(c.find(file("a.bin")));
  c.remember(file("a.bin"), "digest-a");
  const std::optional<std::string> f = c.find(file("a.bin"));
  ASSERT_TRUE(f);
  EXPECT_EQ(*f, "digest-a");
  EXPECT_FALSE(c.find(file("b.bin")));  // never recorded, and missing
}

TEST_F(CheckedFilesTest, ANewSizeOrAReplacedFileIsAnotherFile) {
  write("a.bin", "12345");
  CheckedFiles c;
  c.remember(file("a.bin"), "digest-a");
  fs::last_write_time(file("a.bin"), fs::last_write_time(file("a.bin")) + std::chrono::hours(1));
  EXPECT_TRUE(c.find(file("a.bin")));  // touched (a store marking it used): the same file
  write("a.bin", "123456");  // rewritten in place with another size
  EXPECT_FALSE(c.find(file("a.bin")));
  c.remember(file("a.bin"), "digest-a2");
  write("tmp.bin", "654321");  // replaced by another file of the same size, as a store writes (temp file, rename)
  fs::rename(file("tmp.bin"), file("a.bin"));
  EXPECT_FALSE(c.find(file("a.bin")));
  fs::remove(file("a.bin"));
  EXPECT_FALSE(c.find(file("a.bin")));
}

TEST_F(CheckedFilesTest, TheEarliestRecordedAreForgottenBeyondTheCapacity) {
  CheckedFiles c(2);
  for (const char* n : {"a", "b", "c"}) {
    write(n, n);
    c.remember(file(n), n);
  }
  EXPECT_EQ(c.size(), 2u);
  EXPECT_FALSE(c.find(file("a")));
  EXPECT_TRUE(c.find(file("b")));
  EXPECT_TRUE(c.find(file("c")));
  c.remember(file("b"), "b2");  // recorded again: replaced in place, nothing forgotten
  EXPECT_EQ(c.size(), 2u);
  EXPECT_EQ(*c.find(file("b")), "b2");
  EXPECT_TRUE(c.find(file("c")));
}

TEST_F(CheckedFilesTest, FoldersAreNotRecorded) {
  fs::create_directories(file("d"));
  CheckedFiles c;
  c.remember(file("d"), "x");
  EXPECT_EQ(c.size(), 0u);
}

}  // namespace
}  // namespace tessera
