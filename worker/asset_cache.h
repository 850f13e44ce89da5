// A local content-addressed store of assets (blobs named by their SHA-256), shared safely by several processes.
#pragma once

#include <filesystem>
#include <functional>
#include <mutex>
#include <set>
#include <stdexcept>
#include <string>

namespace tessera::worker {

/// An asset that could not be fetched or failed its hash check.
struct AssetError : std::runtime_error {
  using std::runtime_error::runtime_error;
};

/// Blobs stored as DIR/blobs/<first 2 hex digits>/<sha256>; files appear atomically (temp file + rename), so
/// concurrent workers may share one folder.
class AssetCache {
 public:
  /// Fetches a blob's bytes from elsewhere (e.g. the coordinator); throws on failure.
  using Fetch = std::function<std::string(const std::string& sha256)>;

  /// A cache in dir (created when missing); throws AssetError when it cannot be created.
  explicit AssetCache(std::filesystem::path dir);

  /// The local file holding the blob with this hash: verified once per process when already present (a corrupt file
  /// is replaced), else fetched, verified and stored. Throws AssetError for a malformed hash, bytes that hash to
  /// something else, or I/O errors; exceptions of fetch pass through.
  std::filesystem::path get(const std::string& sha256, const Fetch& fetch);

  /// Where a blob lives (whether or not it is present).
  std::filesystem::path path_of(const std::string& sha256) const;

  /// The cache's folder.
  const std::filesystem::path& dir() const { return dir_; }

 private:
  std::filesystem::path dir_;
  std::mutex mutex_;
  std::set<std::string> verified_;  // hashes checked by this process
};

/// The default cache folder: $XDG_CACHE_HOME/tessera, else ~/.cache/tessera, else a folder under /tmp.
std::filesystem::path default_cache_dir();

}  // namespace tessera::worker
