// read_file_bytes: whole files of every size byte for byte, files whose reported size is not their content (procfs),
// and clear errors for missing files and folders. write_file_atomic (of bytes, or through a writer): a replacement in
// either flush mode leaves the new bytes and no temp file; a failed one leaves the old file and no temp file.
// move_file_atomic: a rename, or a copy across file systems. write_all: every byte through a pipe, the errno of a
// pipe nobody reads. flush_to_disk: a file of several steps flushed whole, the errno of a pipe and of a closed
// descriptor.
#include "core/util/file_io.h"

#include <gtest/gtest.h>
#include <csignal>
#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <random>
#include <string>
#include <vector>

namespace tessera {
namespace file_io_test {  // named: the test files share translation units in a unity build

namespace fs = std::filesystem;

class ReadFileBytes : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() / ("tessera_file_io_" + std::to_string(::getpid()));
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }
  fs::path write(const std::string& name, const std::string& bytes) {
    const fs::path p = dir_ / name;
    std::ofstream(p, std::ios::binary).write(bytes.data(), std::streamsize(bytes.size()));
    return p;
  }
  fs::path dir_;
};

TEST_F(ReadFileBytes, ReadsWholeFilesByteForByte) {
  std::mt19937 rng(3);
  for (const size_t size : {size_t(0), size_t(1), size_t(4095), size_t(4096), size_t(4097), size_t(3) << 20}) {
    std::string bytes(size, '\0');
    for (char& c : bytes) c = char(rng() & 0xff);
    EXPECT_EQ(read_file_bytes(write("f" + std::to_string(size), bytes)), bytes) << size << " bytes";
  }
}

TEST_F(ReadFileBytes, ReadsToTheEndWhateverSizeTheFileReports) {
  // procfs reports a size of 0 for files that hold text.
  const std::string status = read_file_bytes("/proc/self/status");
  EXPECT_NE(status.find("Name:"), std::string::npos);
}

TEST_F(ReadFileBytes, MissingFilesAndFoldersAreErrorsNamingThePath) {
  const fs::path missing = dir_ / "missing.bin";
  try {
    read_file_bytes(missing);
    ADD_FAILURE() << "a missing file was read";
  } catch (const FileError& e) {
    EXPECT_NE(std::string(e.what()).find(missing.string()), std::string::npos) << e.what();
  }
  try {
    read_file_bytes(dir_);
    ADD_FAILURE() << "a folder was read";
  } catch (const FileError& e) {
    EXPECT_NE(std::string(e.what()).find("cannot read " + dir_.string()), std::string::npos) << e.what();
  }
}

TEST_F(ReadFileBytes, AtomicWritesReplaceWholeFilesAndLeaveNoTempFile) {
  const fs::path p = dir_ / "out.bin";
  write_file_atomic(p, "first");
  EXPECT_EQ(read_file_bytes(p), "first");
  write_file_atomic(p, std::string(100000, 'x'), Flush::none);
  EXPECT_EQ(read_file_bytes(p), std::string(100000, 'x'));
  const std::vector<uint8_t> bytes = {0, 1, 2, 255};
  write_file_atomic(p, bytes);
  EXPECT_EQ(read_file_bytes(p), std::string("\0\1\2\xff", 4));
  EXPECT_EQ(std::distance(fs::directory_iterator(dir_), fs::directory_iterator()), 1);  // no temp file left
}

TEST_F(ReadFileBytes, FailedAtomicWriteKeepsTheOldFile) {
  const fs::path p = dir_ / "out.bin";
  write_file_atomic(p, "old");
  fs::create_directories(dir_ / "folder");
  try {
    write_file_atomic(dir_ / "folder", "new");  // the rename over a folder fails
    FAIL() << "replaced a folder";
  } catch (const FileError& e) {
    EXPECT_NE(std::string(e.what()).find("cannot rename"), std::string::npos) << e.what();
  }
  EXPECT_TRUE(fs::is_directory(dir_ / "folder"));
  EXPECT_EQ(read_file_bytes(p), "old");
  EXPECT_EQ(std::distance(fs::directory_iterator(dir_), fs::directory_iterator()), 2);  // no temp file left
}

TEST_F(ReadFileBytes, AtomicWriteThroughAWriterReplacesOrKeepsTheOldFile) {
  const fs::path p = dir_ / "out.bin";
  for (const Flush flush : {Flush::to_disk, Flush::none}) {
    write_file_atomic(p, [](const fs::path& tmp) { std::ofstream(tmp, std::ios::binary) << "made"; }, flush);
    EXPECT_EQ(read_file_bytes(p), "made");
  }
  EXPECT_THROW(write_file_atomic(p, [](const fs::path& tmp) {
    std::ofstream(tmp, std::ios::binary) << "half";
    throw std::runtime_error("the writer failed");
  }), std::runtime_error);
  EXPECT_EQ(read_file_bytes(p), "made");
  EXPECT_EQ(std::distance(fs::directory_iterator(dir_), fs::directory_iterator()), 1);  // no temp file left
}

// A move replaces the target with the file, which leaves its place; a move that cannot be made names both files and
// keeps both; across file systems (where /dev/shm is one of its own) the file is copied and stays.
TEST_F(ReadFileBytes, AMoveReplacesTheTargetOrCopiesAcrossFileSystems) {
  const fs::path from = write("from.bin", "moved"), to = write("to.bin", "old");
  move_file_atomic(from, to);
  EXPECT_EQ(read_file_bytes(to), "moved");
  EXPECT_FALSE(fs::exists(from));
  fs::create_directories(dir_ / "folder");
  const fs::path kept = write("kept.bin", "kept");
  try {
    move_file_atomic(kept, dir_ / "folder");  // a rename over a folder fails
    FAIL() << "replaced a folder";
  } catch (const FileError& e) {
    EXPECT_NE(std::string(e.what()).find("cannot move " + kept.string() + " to "), std::string::npos) << e.what();
  }
  EXPECT_EQ(read_file_bytes(kept), "kept");
  EXPECT_TRUE(fs::is_directory(dir_ / "folder"));
  struct stat shm {}, here {};
  if (::stat("/dev/shm", &shm) != 0 || ::stat(dir_.c_str(), &here) != 0 || shm.st_dev == here.st_dev)
    GTEST_SKIP() << "/dev/shm is missing or on the file system of " << dir_ << ": no move across file systems here";
  const fs::path elsewhere = fs::path("/dev/shm") / ("tessera_file_io_" + std::to_string(::getpid()) + ".bin");
  std::ofstream(elsewhere, std::ios::binary) << "copied";
  move_file_atomic(elsewhere, to);
  EXPECT_EQ(read_file_bytes(to), "copied");
  EXPECT_TRUE(fs::exists(elsewhere));
  fs::remove(elsewhere);
  EXPECT_EQ(std::distance(fs::directory_iterator(dir_), fs::directory_iterator()), 3);  // to, kept, folder: no temp file
}

TEST(WriteAll, WritesEveryByteOrGivesTheErrno) {
  int fds[2];
  ASSERT_EQ(::pipe(fds), 0);
  const std::string bytes(40000, 'x');  // within a pipe's default 64 KiB: no reader needed
  EXPECT_EQ(write_all(fds[1], bytes), 0);
  ::close(fds[1]);
  EXPECT_EQ(read_file_bytes("/dev/fd/" + std::to_string(fds[0])), bytes);
  ::close(fds[0]);

  ASSERT_EQ(::pipe(fds), 0);
  ::close(fds[0]);
  const auto old = std::signal(SIGPIPE, SIG_IGN);
  EXPECT_EQ(write_all(fds[1], "lost"), EPIPE);
  std::signal(SIGPIPE, old);
  ::close(fds[1]);
}

TEST(FlushToDisk, FlushesAFileOfSeveralStepsOrGivesTheErrno) {
  const fs::path file = fs::temp_directory_path() / ("tessera_flush_" + std::to_string(::getpid()));
  std::string bytes(size_t(kFlushStep) * 3 + 12345, '\0');
  std::mt19937 rng(7);
  for (char& c : bytes) c = char(rng());
  const int fd = ::open(file.c_str(), O_RDWR | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
  ASSERT_GE(fd, 0);
  ASSERT_EQ(write_all(fd, bytes), 0);
  EXPECT_EQ(flush_to_disk(fd), 0);
  ::close(fd);
  EXPECT_EQ(read_file_bytes(file), bytes);
  fs::remove(file);

  int fds[2];
  ASSERT_EQ(::pipe(fds), 0);
  EXPECT_EQ(flush_to_disk(fds[1]), EINVAL);  // a pipe has nothing to flush
  ::close(fds[0]);
  ::close(fds[1]);
  EXPECT_EQ(flush_to_disk(fds[1]), EBADF);
}

TEST(TempPathBeside, IsFreshBesideThePathAndEndsInTmp) {
  const fs::path a = temp_path_beside("/data/jobs/j1/result.exr"), b = temp_path_beside("/data/jobs/j1/result.exr");
  EXPECT_NE(a, b);
  EXPECT_EQ(a.parent_path(), fs::path("/data/jobs/j1"));
  EXPECT_EQ(a.extension(), ".tmp");
  EXPECT_EQ(a.filename().string().rfind("result.exr.", 0), 0u) << a;
}

}  // namespace file_io_test
}  // namespace tessera
