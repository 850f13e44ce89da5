#include "server/pixel_files.h"

#include "core/util/file_io.h"
#include "server/storage.h"

#include <system_error>
#include <utility>

namespace fs = std::filesystem;

namespace tessera::server {

namespace {

constexpr const char* kSuffix = ".pixels";
// Files kept open beyond those written since the last flush; more are closed (and opened again when next read).
constexpr size_t kOpenFiles = 64;

}  // namespace

PixelFiles::PixelFiles(fs::path dir, bool durable) : dir_(std::move(dir)), durable_(durable) {
  std::error_code ec;
  const bool existed = fs::is_directory(dir_, ec);
  make_dirs(dir_);
  if (!existed && durable) sync_folder_of(dir_);
}

fs::path PixelFiles::file_of(const std::string& job) const { return dir_ / (job + kSuffix); }

std::shared_ptr<TilePixelFile> PixelFiles::open_locked(const std::string& job, bool create) {
  if (const auto it = open_.find(job); it != open_.end()) return it->second;
  const fs::path path = file_of(job);
  std::error_code ec;
  const bool made = create && !fs::exists(path, ec);
  auto file = std::make_shared<TilePixelFile>(path, create);
  if (file->missing()) return file;  // not kept: an append may make it later
  made_file_ = made_file_ || (made && durable_);
  if (open_.size() >= kOpenFiles)
    std::erase_if(open_, [&](const auto& entry) { return !written_.count(entry.first); });
  open_.emplace(job, file);
  return file;
}

void PixelFiles::close_locked(const std::string& job) {
  open_.erase(job);
  written_.erase(job);
}

PixelRef PixelFiles::append(const std::string& job, std::string_view bytes) {
  std::lock_guard lock(mu_);
  const auto file = open_locked(job, true);
  const PixelRef ref = file->append(bytes);
  if (durable_) written_.emplace(job, file);
  return ref;
}

void PixelFiles::cut(const std::string& job, int64_t size) {
  std::lock_guard lock(mu_);
  open_locked(job, false)->cut(size);
}

std::optional<std::string> PixelFiles::read(const std::string& job, const PixelRef& ref) {
  std::shared_ptr<TilePixelFile> file;
  {
    std::lock_guard lock(mu_);
    file = open_locked(job, false);
  }
  return file->read(ref);  // pread: no lock needed
}

std::vector<fs::path> PixelFiles::sync_written() {
  std::map<std::string, std::shared_ptr<TilePixelFile>> written;
  std::vector<fs::path> doomed;
  bool made = false;
  {
    std::lock_guard lock(mu_);
    written.swap(written_);
    doomed.swap(doomed_);
    made = std::exchange(made_file_, false);
  }
  for (const auto& [job, file] : written) file->sync();
  if (made) sync_folder(dir_);  // the new files' entries
  return doomed;
}

void PixelFiles::remove_when_flushed(const std::string& job) {
  std::lock_guard lock(mu_);
  close_locked(job);
  doomed_.push_back(file_of(job));
}

void PixelFiles::remove(const std::string& job) {
  {
    std::lock_guard lock(mu_);
    close_locked(job);
  }
  delete_files({file_of(job)});
}

void PixelFiles::delete_files(const std::vector<fs::path>& files) {
  for (const fs::path& f : files) {
    std::error_code ec;
    fs::remove(f, ec);
    if (ec) throw StorageError("cannot remove " + f.string() + ": " + ec.message(), ec.value());
  }
}

size_t PixelFiles::keep_only(const std::set<std::string>& jobs) {
  std::vector<fs::path> orphans;
  std::error_code ec;
  for (auto it = fs::directory_iterator(dir_, ec); !ec && it != fs::directory_iterator(); it.increment(ec)) {
    const fs::path& p = it->path();
    if (p.extension() != kSuffix || jobs.count(p.stem().string())) continue;
    orphans.push_back(p);
  }
  if (ec) throw StorageError("cannot list " + dir_.string() + ": " + ec.message(), ec.value());
  {
    std::lock_guard lock(mu_);
    for (const fs::path& p : orphans) close_locked(p.stem().string());
  }
  delete_files(orphans);
  return orphans.size();
}

}  // namespace tessera::server
