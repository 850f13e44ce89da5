// A job's pixel file: appends read back whole, damaged or missing bytes read as nothing, a cut undoes appends, and a
// reopened file goes on at its end.
#include "server/tile_pixel_file.h"

#include "core/util/file_io.h"
#include "server/pixel_files.h"
#include "server/storage.h"

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <string>

namespace tessera::server {
namespace {

namespace fs = std::filesystem;

struct TilePixelFileTest : ::testing::Test {
  fs::path dir = fs::temp_directory_path() / ("tessera-pixel-file-test-" + random_hex(6));
  void SetUp() override { fs::create_directories(dir); }
  void TearDown() override { fs::remove_all(dir); }
};

TEST_F(TilePixelFileTest, AppendsReadBackAndAReopenedFileGoesOnAtItsEnd) {
  const std::string one(5000, 'a'), two = "second tile";
  PixelRef r1, r2;
  {
    TilePixelFile f(dir / "j.pixels", true);
    r1 = f.append(one);
    r2 = f.append(two);
    f.sync();
    EXPECT_EQ(r1.offset, 0);
    EXPECT_EQ(r1.length, 5000);
    EXPECT_EQ(r2.offset, 5000);
    EXPECT_EQ(f.read(r1), one);
    EXPECT_EQ(f.read(r2), two);
  }
  EXPECT_EQ(fs::file_size(dir / "j.pixels"), 5000u + two.size());  // the reserved space is not in its size
  TilePixelFile f(dir / "j.pixels", true);
  EXPECT_EQ(f.read(r2), two);
  const PixelRef r3 = f.append("third");
  EXPECT_EQ(r3.offset, r2.offset + r2.length);
  EXPECT_EQ(f.read(r3), "third");
}

TEST_F(TilePixelFileTest, DamagedCutOrMissingBytesReadAsNothing) {
  TilePixelFile f(dir / "j.pixels", true);
  const PixelRef r1 = f.append(std::string(1000, 'x'));
  const PixelRef r2 = f.append(std::string(1000, 'y'));
  {
    std::fstream s(dir / "j.pixels", std::ios::in | std::ios::out | std::ios::binary);
    s.seekp(500);
    s.put('z');
  }
  EXPECT_FALSE(f.read(r1));  // fails its checksum
  EXPECT_TRUE(f.read(r2));
  fs::resize_file(dir / "j.pixels", 1999);
  EXPECT_FALSE(f.read(r2));  // the file ends inside it
  EXPECT_FALSE(f.read(PixelRef{5000, 10, 0}));
  EXPECT_FALSE(TilePixelFile(dir / "none.pixels", false).read(r1));
  EXPECT_FALSE(fs::exists(dir / "none.pixels"));  // opened without create: not made
  EXPECT_NE(pixel_checksum(std::string(1000, 'x')), pixel_checksum(std::string(999, 'x') + 'y'));
  EXPECT_NE(pixel_checksum(std::string(64, '\0')), pixel_checksum(std::string(65, '\0')));
}

TEST_F(TilePixelFileTest, ACutUndoesAppends) {
  TilePixelFile f(dir / "j.pixels", true);
  const PixelRef kept = f.append("kept");
  const PixelRef undone = f.append("undone");
  f.cut(undone.offset);
  EXPECT_EQ(f.size(), kept.length);
  EXPECT_EQ(fs::file_size(dir / "j.pixels"), 4u);
  EXPECT_FALSE(f.read(undone));
  EXPECT_EQ(f.append("next").offset, undone.offset);
}

TEST_F(TilePixelFileTest, PixelFilesFlushWhatWasWrittenAndDeleteFilesOfPurgedJobsAfterIt) {
  PixelFiles files(dir / "pixels", true);
  const PixelRef r = files.append("j-1", "bytes of j-1");
  files.append("j-2", "bytes of j-2");
  EXPECT_EQ(files.read("j-1", r), "bytes of j-1");
  files.remove_when_flushed("j-2");
  EXPECT_TRUE(fs::exists(files.file_of("j-2")));  // the purge is not on the disk yet
  const auto doomed = files.sync_written();
  ASSERT_EQ(doomed.size(), 1u);
  EXPECT_EQ(doomed[0], files.file_of("j-2"));
  PixelFiles::delete_files(doomed);
  EXPECT_FALSE(fs::exists(files.file_of("j-2")));
  EXPECT_TRUE(files.sync_written().empty());
  files.append("j-3", "orphan");
  EXPECT_EQ(files.keep_only({"j-1"}), 1u);
  EXPECT_FALSE(fs::exists(files.file_of("j-3")));
  EXPECT_EQ(files.read("j-1", r), "bytes of j-1");
}

}  // namespace
}  // namespace tessera::server
