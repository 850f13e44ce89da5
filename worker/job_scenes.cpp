#include "worker/job_scenes.h"

#include "core/scene_loader.h"

#include <map>
#include <utility>

namespace tessera::farm {

JobScenes::JobScenes(std::filesystem::path cache_dir, size_t jobs, size_t image_bytes)
    : assets_(std::move(cache_dir)), scenes_(jobs), images_(4096, image_bytes) {}

std::shared_ptr<const PreparedJob> JobScenes::find(const std::string& job) {
  std::lock_guard lock(mutex_);
  return scenes_.find(job);
}

std::vector<std::string> JobScenes::jobs() {
  std::lock_guard lock(mutex_);
  return scenes_.keys();
}

std::shared_ptr<const PreparedJob> JobScenes::build(const std::string& job, const protocol::JobSpec& spec,
                                                    const AssetCache::Fetch& fetch_blob) {
  std::map<std::string, std::filesystem::path> files;
  for (const auto& [path, hash] : spec.assets) {
    try {
      files[path] = assets_.get(hash, fetch_blob);
    } catch (const Gone& e) {
      throw AssetError("asset " + path + " (" + hash + ") is not on the coordinator: " + e.what());
    }
  }
  const AssetResolver resolve = [&files](const std::string& path, const std::string& json_path) {
    const auto it = files.find(path);
    if (it == files.end()) throw SceneError(json_path + ": asset '" + path + "' is not listed in the job's assets");
    return it->second;
  };
  // The spec's spp is already the job's (the scene's unless overridden): the loader is not told again.
  LoadOptions lo = spec.sampling.load_options();
  lo.spp.reset();
  lo.checked_files = &images_;  // the cache's files are named by their content and never rewritten
  auto prepared = std::make_shared<PreparedJob>();
  prepared->loaded = load_scene_json(spec.scene, "job " + job, resolve, lo);
  prepared->sampling = spec.sampling;
  const Scene& built = prepared->loaded.scene;
  if (built.width != spec.width || built.height != spec.height)
    throw SceneError("job " + job + ": the scene is " + std::to_string(built.width) + "x" + std::to_string(built.height) +
                     " but the job spec says " + std::to_string(spec.width) + "x" + std::to_string(spec.height));
  std::lock_guard lock(mutex_);
  scenes_.put(job, prepared);
  return prepared;
}

}  // namespace tessera::farm
