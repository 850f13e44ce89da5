// CheckedFiles: an entry is found while its path names the same file with the same size (touching it does not
// matter), the least recently used files are forgotten beyond the capacity, and pixels are kept within the budget.
#include "core/scene/checked_files.h"

#include "tests/support/test_files.h"

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
  const std::optional<CheckedFiles::Record> f = c.find(file("a.bin"));
  ASSERT_TRUE(f);
  EXPECT_EQ(f->sha256, "digest-a");
  EXPECT_EQ(f->image, nullptr);
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

TEST_F(CheckedFilesTest, TheLeastRecentlyUsedAreForgottenBeyondTheCapacity) {
  CheckedFiles c(2);
  for (const char* n : {"a", "b", "c"}) {
    write(n, n);
    c.remember(file(n), n);
  }
  EXPECT_EQ(c.size(), 2u);
  EXPECT_FALSE(c.find(file("a")));
  EXPECT_TRUE(c.find(file("b")));  // b is now used more recently than c
  c.remember(file("b"), "b2");  // recorded again: replaced, nothing forgotten
  EXPECT_EQ(c.size(), 2u);
  EXPECT_EQ(c.find(file("b"))->sha256, "b2");
  EXPECT_TRUE(c.find(file("c")));
  c.remember(file("a"), "a");  // b is the least recently used now
  EXPECT_FALSE(c.find(file("b")));
  EXPECT_TRUE(c.find(file("c")));
}

TEST_F(CheckedFilesTest, PixelsAreKeptWithinTheBudgetForTheMostRecentlyUsed) {
  const auto image = [](int w) { return std::make_shared<const Image>(Image::make(w, 1)); };  // 12 bytes per pixel
  CheckedFiles c(16, 12 * 9);
  for (const char* n : {"a", "b", "c"}) write(n, n);
  c.remember(file("a"), "a", image(4));
  c.remember(file("b"), "b", image(4));
  EXPECT_EQ(c.image_bytes(), 96u);
  ASSERT_NE(c.find(file("a"))->image, nullptr);  // a is now used more recently than b
  c.remember(file("c"), "c", image(2));          // 120 bytes, over the budget of 108: b's pixels go
  EXPECT_EQ(c.image_bytes(), 72u);
  EXPECT_EQ(c.find(file("b"))->image, nullptr);
  EXPECT_EQ(c.find(file("b"))->sha256, "b");     // its digest stays
  EXPECT_NE(c.find(file("a"))->image, nullptr);
  EXPECT_NE(c.find(file("c"))->image, nullptr);
  c.remember(file("b"), "b", image(11));         // larger than the whole budget: never kept, nothing pushed out
  EXPECT_EQ(c.find(file("b"))->image, nullptr);
  EXPECT_EQ(c.image_bytes(), 72u);
  CheckedFiles none;                              // no budget: digests only
  none.remember(file("a"), "a", image(1));
  EXPECT_EQ(none.find(file("a"))->image, nullptr);
  EXPECT_EQ(none.image_bytes(), 0u);
}

TEST_F(CheckedFilesTest, AnEnvironmentTableGoesWithThePixelsItWasBuiltFrom) {
  const auto image = [](int w) { return std::make_shared<const Image>(Image::make(w, 1)); };
  const std::vector<float> weights(8, 1.f);
  const auto table = std::make_shared<const Distribution2D>(weights, 4, 2);
  for (const char* n : {"a", "b"}) write(n, n);
  CheckedFiles c(16, 1 << 20);
  const auto pixels = image(4);
  c.remember(file("a"), "a", pixels);
  c.remember_environment(file("a"), image(4).get(), table);  // other pixels than the record's: not taken
  EXPECT_EQ(c.find(file("a"))->environment, nullptr);
  c.remember_environment(file("b"), pixels.get(), table);  // a file never recorded: nothing
  EXPECT_FALSE(c.find(file("b")));
  c.remember_environment(file("a"), pixels.get(), table);
  EXPECT_EQ(c.find(file("a"))->environment, table);
  EXPECT_EQ(c.image_bytes(), 48u + table->bytes());
  c.remember(file("a"), "a", pixels);  // recorded again: the record starts without a table
  EXPECT_EQ(c.find(file("a"))->environment, nullptr);
  EXPECT_EQ(c.image_bytes(), 48u);
  // Within the budget only, and dropped with its pixels.
  CheckedFiles small(16, 48 + table->bytes() - 1);
  small.remember(file("a"), "a", pixels);
  small.remember_environment(file("a"), pixels.get(), table);
  EXPECT_EQ(small.find(file("a"))->environment, nullptr);
  CheckedFiles fits(16, 48 + table->bytes());
  fits.remember(file("a"), "a", pixels);
  fits.remember_environment(file("a"), pixels.get(), table);
  ASSERT_EQ(fits.find(file("a"))->environment, table);
  fits.remember(file("b"), "b", image(1));  // over the budget: a's pixels and table go together
  EXPECT_EQ(fits.find(file("a"))->image, nullptr);
  EXPECT_EQ(fits.find(file("a"))->environment, nullptr);
  EXPECT_EQ(fits.image_bytes(), 12u);
}

TEST_F(CheckedFilesTest, FoldersAreNotRecorded) {
  fs::create_directories(file("d"));
  CheckedFiles c;
  c.remember(file("d"), "x");
  EXPECT_EQ(c.size(), 0u);
}

}  // namespace
}  // namespace tessera
