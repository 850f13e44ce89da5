#include "worker/job_scenes.h"

#include "core/scene/scene_loader.h"

#include <map>
#include <utility>

namespace tessera::worker {

namespace {

// What loading a job's scene takes from its sampling settings: the spp is the renderer's, not the loader's.
LoadOptions loading(const protocol::SamplingSettings& sampling) {
  LoadOptions lo = sampling.load_options();
  lo.spp.reset();
  return lo;
}

}  // namespace

JobScenes::JobScenes(std::filesystem::path cache_dir, size_t jobs, size_t image_bytes, AssetLimits limits)
    : assets_(std::move(cache_dir)), scenes_(jobs), limits_(limits), images_(4096, image_bytes) {}

std::shared_ptr<const PreparedJob> JobScenes::find(const std::string& job) {
  std::lock_guard lock(mutex_);
  return scenes_.find(job);
}

std::vector<std::string> JobScenes::jobs() {
  std::lock_guard lock(mutex_);
  return scenes_.keys();
}

LoadedScene JobScenes::load(const std::string& label, const nlohmann::json& scene,
                            const std::map<std::string, std::string>& assets, const protocol::SamplingSettings& sampling,
                            const AssetCache::Fetch& fetch_blob) {
  std::map<std::string, std::filesystem::path> files;
  for (const auto& [path, hash] : assets) {
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
  LoadOptions lo = loading(sampling);
  lo.checked_files = &images_;  // the cache's files are named by their content and never rewritten
  lo.asset_limits = limits_;
  return load_scene_json(scene, label, resolve, lo);
}

std::shared_ptr<const PreparedJob> JobScenes::build(const std::string& job, const protocol::JobSpec& spec,
                                                    const AssetCache::Fetch& fetch_blob) {
  auto prepared = std::make_shared<PreparedJob>();
  std::optional<LoadedScene> preloaded;
  if (preload_ && preload_->expected.scene == spec.scene && preload_->expected.assets == spec.assets &&
      loading(preload_->expected.sampling) == loading(spec.sampling)) {
    Preload p = std::move(*preload_);
    preload_.reset();
    try {
      preloaded = p.scene.get();
      ++preloads_used_;
    } catch (const std::exception&) {
      // loaded again below, which reports what is wrong
    }
  } else if (preload_) {
    preload_->scene.wait();  // one scene load at a time: they would share the same cores
  }
  prepared->loaded = preloaded ? std::move(*preloaded) : load("job " + job, spec.scene, spec.assets, spec.sampling, fetch_blob);
  prepared->sampling = spec.sampling;
  const Scene& built = prepared->loaded.scene;
  if (built.width != spec.width || built.height != spec.height)
    throw SceneError("job " + job + ": the scene is " + std::to_string(built.width) + "x" + std::to_string(built.height) +
                     " but the job spec says " + std::to_string(spec.width) + "x" + std::to_string(spec.height));
  std::lock_guard lock(mutex_);
  scenes_.put(job, prepared);
  return prepared;
}

void JobScenes::preload(protocol::JobSubmission expected) {
  Preload p{std::move(expected), {}};
  p.scene = std::async(std::launch::async, [this, scene = p.expected.scene, assets = p.expected.assets,
                                            sampling = p.expected.sampling] {
    return load("the expected job", scene, assets, sampling,
                [](const std::string& hash) -> std::string { throw AssetError(hash + " is not in the cache yet"); });
  });
  preload_ = std::move(p);
}

}  // namespace tessera::worker
