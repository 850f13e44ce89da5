#include "server/storage.h"

#include "core/util/sha256.h"
#include "core/util/file_io.h"

#include <cerrno>
#include <chrono>

namespace fs = std::filesystem;

namespace tessera::server {

DiskFullError::DiskFullError(const std::string& what) : StorageError(what, ENOSPC) {}

bool is_disk_full(const std::exception& e) {
  const auto* f = dynamic_cast<const StorageError*>(&e);
  return f && (f->error == ENOSPC || f->error == EDQUOT);
}

void make_dirs(const fs::path& dir) {
  std::error_code ec;
  fs::create_directories(dir, ec);
  if (ec) throw StorageError("cannot create " + dir.string() + ": " + ec.message(), ec.value());
}

size_t remove_leftovers(const fs::path& dir, bool everything) {
  std::error_code ec;
  std::vector<fs::path> doomed;
  for (auto it = fs::recursive_directory_iterator(dir, ec); !ec && it != fs::recursive_directory_iterator(); it.increment(ec)) {
    const fs::path& p = it->path();
    if (everything) {
      doomed.push_back(p);
      it.disable_recursion_pending();  // the whole entry goes
    } else if (it->is_regular_file() && p.extension() == ".tmp") {
      doomed.push_back(p);
    }
  }
  if (ec) throw StorageError("cannot list " + dir.string() + ": " + ec.message());
  for (const fs::path& p : doomed) {
    fs::remove_all(p, ec);
    if (ec) throw StorageError("cannot remove " + p.string() + ": " + ec.message());
  }
  return doomed.size();
}

DiskBlobStore::DiskBlobStore(fs::path dir, Durability durability) : dir_(std::move(dir)), durability_(durability) {
  make_dirs(dir_);
  leftovers_removed_ = remove_leftovers(dir_);  // blob writes a crash interrupted
}

fs::path blobs_dir(const fs::path& data_dir) { return data_dir / "blobs"; }

fs::path blob_file(const fs::path& dir, const std::string& sha) { return dir / sha.substr(0, 2) / sha; }

PutBlobResult DiskBlobStore::put(const std::string& sha, std::string_view bytes) {
  if (!is_sha256_hex(sha)) throw std::invalid_argument("not a SHA-256: " + sha);
  PutBlobResult r;
  r.size = bytes.size();
  r.actual = sha256_hex(bytes);
  if (r.actual != sha) {
    r.status = PutBlobResult::mismatch;
    return r;
  }
  const fs::path p = path_of(sha);
  std::error_code ec;
  // Blobs are immutable and were verified when written: a repeat upload writes nothing but starts the blob's grace
  // period (see Collector) again.
  if (fs::is_regular_file(p, ec)) {
    fs::last_write_time(p, fs::file_time_type::clock::now(), ec);
    r.status = PutBlobResult::existed;
    return r;
  }
  make_dirs(p.parent_path());
  write_file_atomic(p, bytes, flush_for(durability_));
  r.status = PutBlobResult::created;
  return r;
}

bool DiskBlobStore::has(const std::string& sha) {
  if (!is_sha256_hex(sha)) return false;
  std::error_code ec;
  return fs::is_regular_file(path_of(sha), ec);
}

std::optional<fs::path> DiskBlobStore::file(const std::string& sha) {
  if (!has(sha)) return std::nullopt;
  return path_of(sha);
}

bool DiskBlobStore::touch(const std::string& sha) {
  if (!has(sha)) return false;
  std::error_code ec;
  fs::last_write_time(path_of(sha), fs::file_time_type::clock::now(), ec);
  return !ec;
}

std::vector<std::pair<std::string, int64_t>> DiskBlobStore::list() {
  std::vector<std::pair<std::string, int64_t>> out;
  std::error_code ec;
  for (auto it = fs::recursive_directory_iterator(dir_, ec); !ec && it != fs::recursive_directory_iterator();
       it.increment(ec)) {
    const std::string name = it->path().filename().string();
    if (!it->is_regular_file() || !is_sha256_hex(name)) continue;
    std::error_code tec;
    const auto t = fs::last_write_time(it->path(), tec);
    if (tec) continue;  // removed meanwhile
    const auto sys = fs::file_time_type::clock::to_sys(t);
    out.emplace_back(name, std::chrono::duration_cast<std::chrono::milliseconds>(sys.time_since_epoch()).count());
  }
  if (ec) throw StorageError("cannot list " + dir_.string() + ": " + ec.message());
  return out;
}

void DiskBlobStore::remove(const std::string& sha) {
  if (!is_sha256_hex(sha)) return;
  std::error_code ec;
  fs::remove(path_of(sha), ec);
  if (ec) throw StorageError("cannot remove " + path_of(sha).string() + ": " + ec.message());
}

}  // namespace tessera::server
