#include "server/coordinator_store.h"

#include "core/util/file_io.h"
#include "server/database.h"
#include "server/memory_store.h"

namespace tessera::server {

namespace fs = std::filesystem;

fs::path job_result_file(const fs::path& dir, const std::string& job) { return dir / "jobs" / job / "result.exr"; }

CoordinatorStore::CoordinatorStore(const fs::path& dir, Durability durability)
    : jobs_dir_(dir / "jobs"), scratch_(dir / "tmp"), durability_(durability), dir_(dir) {
  make_dirs(jobs_dir_);
  make_dirs(scratch_);
}

fs::path CoordinatorStore::result_path(const std::string& job) {
  make_dirs(jobs_dir_ / job);
  return job_result_file(dir_, job);
}

void CoordinatorStore::write_result(const std::string& job, const std::function<void(const fs::path&)>& write) {
  write_file_atomic(result_path(job), write, flush_for(durability_));
}

void CoordinatorStore::remove_outputs(const std::string& job) {
  std::error_code ec;
  fs::remove_all(jobs_dir_ / job, ec);
  if (ec) throw StorageError("cannot remove " + (jobs_dir_ / job).string() + ": " + ec.message());
}

std::vector<std::string> CoordinatorStore::jobs_with_outputs() {
  std::vector<std::string> out;
  std::error_code ec;
  for (auto it = fs::directory_iterator(jobs_dir_, ec); !ec && it != fs::directory_iterator(); it.increment(ec))
    if (it->is_directory()) out.push_back(it->path().filename().string());
  if (ec) throw StorageError("cannot list " + jobs_dir_.string() + ": " + ec.message());
  return out;
}

std::unique_ptr<CoordinatorStore> open_coordinator_store(const fs::path& dir, Durability durability) {
  if (durability == Durability::none) return std::make_unique<MemoryStore>(dir);
  return std::make_unique<DurableStore>(dir, durability);
}

}  // namespace tessera::server
