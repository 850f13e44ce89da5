#include "worker/asset_cache.h"

#include "core/util/file_io.h"
#include "core/util/sha256.h"

#include <unistd.h>

#include <cstdlib>
#include <system_error>

namespace tessera::worker {

namespace fs = std::filesystem;

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
  try {
    write_file_atomic(path, bytes, Flush::none);  // a cache: a file lost in a crash is fetched again
  } catch (const FileError& e) {
    throw AssetError(e.what());
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

}  // namespace tessera::worker
