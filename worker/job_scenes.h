// The scenes of the jobs a worker renders: each built once, from its spec and its assets in the worker's cache, and
// kept for the job's later tiles.
#pragma once

#include "core/scene/checked_files.h"
#include "protocol/messages.h"
#include "worker/asset_cache.h"
#include "worker/prefetched_lease.h"
#include "worker/scene_cache.h"

#include <filesystem>
#include <future>
#include <memory>
#include <mutex>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

namespace tessera::worker {

/// What fetching from the coordinator throws when it no longer has the job, lease or blob asked for (404).
struct Gone : std::runtime_error {
  using std::runtime_error::runtime_error;
};

/// Built scenes by job id (the most recently used few), the asset cache they are built from, and decoded textures
/// kept across jobs. find() and jobs() are thread-safe; preload() and build() are called by one thread at a time.
class JobScenes {
 public:
  /// Assets cached in `cache_dir`; the scenes of the `jobs` most recently used jobs kept, decoded images up to
  /// `image_bytes`; every scene loaded with `limits` on its assets. Throws AssetError when the cache folder cannot be
  /// created.
  JobScenes(std::filesystem::path cache_dir, size_t jobs, size_t image_bytes, AssetLimits limits = {});

  /// The asset cache's folder.
  const std::filesystem::path& cache_dir() const { return assets_.dir(); }

  /// The job's built scene (now the most recently used), or null when none is held.
  std::shared_ptr<const PreparedJob> find(const std::string& job);

  /// The jobs whose scenes are held, most recently used first.
  std::vector<std::string> jobs();

  /// Builds and keeps the scene of `job` from its spec; assets missing from the cache are fetched by hash through
  /// `fetch_blob`, whose Gone becomes an AssetError naming the asset. Throws SceneError for a scene that does not load
  /// or whose size is not the spec's.
  std::shared_ptr<const PreparedJob> build(const std::string& job, const protocol::JobSpec& spec,
                                           const AssetCache::Fetch& fetch_blob);

  /// Begins loading, on a thread of its own, the scene of a job expected to be leased soon, from assets already in the
  /// cache: the first build() whose spec has the same scene, assets and loading settings takes that scene instead of
  /// loading its own; a build() of another job waits for the preload to end first (one load at a time). A preload
  /// that fails is dropped without a word (that job's build then loads and reports).
  void preload(protocol::JobSubmission expected);

  /// Builds that took a preloaded scene.
  int preloads_used() const { return preloads_used_; }

 private:
  struct Preload {
    protocol::JobSubmission expected;
    std::future<LoadedScene> scene;
  };

  // The scene of a job's (or an expected job's) spec, from its assets in the cache.
  LoadedScene load(const std::string& label, const nlohmann::json& scene, const std::map<std::string, std::string>& assets,
                   const protocol::SamplingSettings& sampling, const AssetCache::Fetch& fetch_blob);

  AssetCache assets_;
  std::mutex mutex_;  // guards scenes_ (looked up by the companion's thread too)
  LruCache<PreparedJob> scenes_;
  AssetLimits limits_;
  CheckedFiles images_;  // decoded textures of earlier jobs, by cache file (thread-safe: a preload uses it too)
  std::optional<Preload> preload_;  // until a build takes it
  int preloads_used_ = 0;
};

}  // namespace tessera::worker
