#include "worker/asset_cache.h"

#include "core/sha256.h"

#include <fcntl.h>
#include <unistd.h>

#include <atomic>
#include <cerrno>
#include <cstdlib>
#include <cstring>
#include <system_error>

namespace tessera::farm {

namespace fs = std::filesystem;

namespace {

void write_whole_file(const fs::path& path, const std::string& bytes) {
  const int fd = ::open(path.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0644);
  if (fd < 0) throw AssetError("cannot create " + path.string() + ": " + std::strerror(errno));
  size_t done = 0;
  while (done < bytes.size()) {
    const ssize_t n = ::write(fd, bytes.data() + done, bytes.size() - done);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) {
      const int err = n < 0 ? errno : EIO;
      ::close(fd);
      ::unlink(path.c_str());
      throw AssetError("cannot write " + path.string() + ": " + std::strerror(err));
    }
    done += size_t(n);
  }
  if (::close(fd) != 0) {
    const int err = errno;
    ::unlink(path.c_str());
    throw AssetError("cannot close " + path.string() + ": " + std::strerror(err));
  }
}

}  // namespace

AssetCache::AssetCache(fs::path dir) : dir_(std::move(dir)) {
  std::error_code ec;
  fs::create_directories(dir_ / "blobs", ec);
  if (ec) throw AssetError("cannot create the asset cache " + (dir_ / "blobs").string() + ": " + ec.message());
}

fs::path AssetCache::path_of(const std::string& sha256) const { return dir_ / "blobs" / sha256.substr(0, 2) / sha256; }

fs::path AssetCache::get(const std::string& sha256, const Fetch& fetch) {
  if (!is_sha256_hex(sha256)) throw AssetError("'" + sha256 + "' is not a lowercase hex SHA-256");
  const fs::path path = path_of(sha256);
  {
    std::lock_guard lock(mutex_);
    if (verified_.count(sha256)) return path;
  }
  std::error_code ec;
  if (fs::exists(path, ec)) {
    std::string actual;
    try {
      actual = sha256_file(path);
    } catch (const std::exception&) {
      actual.clear();
    }
    if (actual == sha256) {
      std::lock_guard lock(mutex_);
      verified_.insert(sha256);
      return path;
    }
    fs::remove(path, ec);  // corrupt or unreadable: fetch it again
  }

  const std::string bytes = fetch(sha256);
  const std::string actual = sha256_hex(bytes);
  if (actual != sha256)
    throw AssetError("blob " + sha256 + " arrived with " + std::to_string(bytes.size()) + " bytes hashing to " + actual);
  fs::create_directories(path.parent_path(), ec);
  if (ec) throw AssetError("cannot create " + path.parent_path().string() + ": " + ec.message());
  static std::atomic<uint64_t> counter{0};
  fs::path tmp = path;
  tmp += ".tmp." + std::to_string(::getpid()) + "." + std::to_string(counter++);
  write_whole_file(tmp, bytes);
  if (::rename(tmp.c_str(), path.c_str()) != 0) {
    const int err = errno;
    ::unlink(tmp.c_str());
    throw AssetError("cannot rename " + tmp.string() + " to " + path.string() + ": " + std::strerror(err));
  }
  std::lock_guard lock(mutex_);
  verified_.insert(sha256);
  return path;
}

fs::path default_cache_dir() {
  if (const char* x = std::getenv("XDG_CACHE_HOME"); x && *x) return fs::path(x) / "tessera";
  if (const char* h = std::getenv("HOME"); h && *h) return fs::path(h) / ".cache" / "tessera";
  return fs::temp_directory_path() / ("tessera-cache-" + std::to_string(::getuid()));
}

}  // namespace tessera::farm
