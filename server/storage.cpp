#include "server/storage.h"

#include "core/sha256.h"
#include "core/file_io.h"

#include <fcntl.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <fstream>
#include <random>
#include <sstream>

namespace fs = std::filesystem;

namespace tessera::server {


void make_dirs(const fs::path& dir) {
  std::error_code ec;
  fs::create_directories(dir, ec);
  if (ec) throw StorageError("cannot create " + dir.string() + ": " + ec.message());
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

DiskBlobStore::DiskBlobStore(fs::path dir) : dir_(std::move(dir)) {
  make_dirs(dir_);
  leftovers_removed_ = remove_leftovers(dir_);  // blob writes a crash interrupted
}

fs::path DiskBlobStore::path_of(const std::string& sha) const { return dir_ / sha.substr(0, 2) / sha; }

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
  // Blobs are immutable and were verified when written: a repeat upload writes nothing.
  if (fs::is_regular_file(p, ec)) {
    r.status = PutBlobResult::existed;
    return r;
  }
  make_dirs(p.parent_path());
  write_file_atomic(p, bytes);
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

std::optional<std::string> DiskBlobStore::read(const std::string& sha) {
  if (!has(sha)) return std::nullopt;
  return read_file_bytes(path_of(sha));
}

}  // namespace tessera::server
