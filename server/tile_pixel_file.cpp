#include "server/tile_pixel_file.h"

#include "server/storage.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstring>

namespace tessera::server {

namespace {

// Space reserved ahead of the appends, so that most appends need no fallocate of their own.
constexpr int64_t kReserveStep = int64_t(1) << 20;

[[noreturn]] void fail(const std::string& what, const std::filesystem::path& path, int err) {
  const std::string text = "cannot " + what + " " + path.string() + ": " + std::strerror(err);
  if (err == ENOSPC || err == EDQUOT) throw DiskFullError(text);
  throw StorageError(text, err);
}

uint64_t load64(const char* p) {
  uint64_t w;
  std::memcpy(&w, p, sizeof w);
  return w;
}

uint64_t mix(uint64_t h) {
  h ^= h >> 33;
  h *= 0xff51afd7ed558ccdull;
  h ^= h >> 33;
  h *= 0xc4ceb9fe1a85ec53ull;
  h ^= h >> 33;
  return h;
}

}  // namespace

uint64_t pixel_checksum(std::string_view bytes) {
  // Four independent lanes of multiply-xor over 8-byte words (so they run side by side), then the tail and the
  // length, mixed together.
  constexpr uint64_t k = 0x9e3779b97f4a7c15ull;
  uint64_t lane[4] = {0x243f6a8885a308d3ull, 0x13198a2e03707344ull, 0xa4093822299f31d0ull, 0x082efa98ec4e6c89ull};
  const char* p = bytes.data();
  const size_t n = bytes.size();
  size_t i = 0;
  for (; i + 32 <= n; i += 32)
    for (int l = 0; l < 4; ++l) lane[l] = ((lane[l] ^ load64(p + i + 8 * l)) * k) + uint64_t(l + 1);
  uint64_t tail = 0xcbf29ce484222325ull;  // FNV-1a over the last bytes
  for (; i < n; ++i) tail = (tail ^ uint8_t(p[i])) * 0x100000001b3ull;
  uint64_t h = mix(n ^ k);
  for (uint64_t l : lane) h = mix(h ^ l);
  return mix(h ^ tail);
}

TilePixelFile::TilePixelFile(std::filesystem::path path, bool create) : path_(std::move(path)) {
  fd_ = ::open(path_.c_str(), O_RDWR | O_CLOEXEC | (create ? O_CREAT : 0), 0644);
  if (fd_ < 0) {
    if (!create && errno == ENOENT) return;
    fail("open", path_, errno);
  }
  struct stat st {};
  if (::fstat(fd_, &st) != 0) {
    const int err = errno;
    ::close(fd_);
    fail("read the size of", path_, err);
  }
  end_ = reserved_ = st.st_size;
}

TilePixelFile::~TilePixelFile() {
  if (fd_ >= 0) ::close(fd_);
}

PixelRef TilePixelFile::append(std::string_view bytes) {
  if (fd_ < 0) fail("append to", path_, ENOENT);
  const PixelRef ref{end_, int64_t(bytes.size()), pixel_checksum(bytes)};
  const int64_t end = end_ + ref.length;
  if (end > reserved_) {
    // Allocated now, so that writing the pages back later cannot find the disk full; the file's size is left to the
    // writes. Near a full disk, only what this append needs.
    int rc = ::fallocate(fd_, FALLOC_FL_KEEP_SIZE, reserved_, std::max(end, reserved_ + kReserveStep) - reserved_);
    if (rc == 0) {
      reserved_ = std::max(end, reserved_ + kReserveStep);
    } else if (errno == ENOSPC || errno == EDQUOT) {
      rc = ::fallocate(fd_, FALLOC_FL_KEEP_SIZE, reserved_, end - reserved_);
      if (rc != 0) fail("make room in", path_, errno);
      reserved_ = end;
    } else if (errno != EOPNOTSUPP && errno != ENOSYS) {
      fail("make room in", path_, errno);
    }
  }
  size_t done = 0;
  while (done < bytes.size()) {
    const ssize_t n = ::pwrite(fd_, bytes.data() + done, bytes.size() - done, ref.offset + int64_t(done));
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) {
      const int err = n < 0 ? errno : ENOSPC;
      if (::ftruncate(fd_, end_) == 0) reserved_ = end_;  // no partial tile is left behind
      fail("append to", path_, err);
    }
    done += size_t(n);
  }
  end_ = end;
  return ref;
}

std::optional<std::string> TilePixelFile::read(const PixelRef& ref) const {
  if (fd_ < 0 || ref.offset < 0 || ref.length < 0) return std::nullopt;
  std::string bytes(size_t(ref.length), '\0');
  size_t done = 0;
  while (done < bytes.size()) {
    const ssize_t n = ::pread(fd_, bytes.data() + done, bytes.size() - done, ref.offset + int64_t(done));
    if (n < 0 && errno == EINTR) continue;
    if (n < 0) fail("read", path_, errno);
    if (n == 0) return std::nullopt;  // the file ends before the tile does
    done += size_t(n);
  }
  if (pixel_checksum(bytes) != ref.checksum) return std::nullopt;
  return bytes;
}

void TilePixelFile::sync() {
  if (fd_ >= 0 && ::fdatasync(fd_) != 0) fail("flush", path_, errno);
}

void TilePixelFile::cut(int64_t size) {
  if (fd_ < 0 || size >= end_) return;
  if (::ftruncate(fd_, size) != 0) fail("cut back", path_, errno);
  end_ = reserved_ = size;
}

}  // namespace tessera::server
