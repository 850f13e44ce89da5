// The coordinator's storage behind interfaces: a content-addressed blob store and per-job records and results.
#pragma once

#include "core/util/file_io.h"

#include <nlohmann/json.hpp>

#include <cstdint>
#include <filesystem>
#include <functional>
#include <optional>
#include <stdexcept>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

namespace tessera::server {

/// A storage operation that failed for a reason other than the caller's input (disk full, permissions).
using StorageError = FileError;

/// A write that failed because the file system holding the data folder has no room left (SQLite's SQLITE_FULL).
struct DiskFullError : StorageError {
  explicit DiskFullError(const std::string& what);
};

/// True when `e` says the disk is full: a DiskFullError, or a StorageError from ENOSPC or EDQUOT.
bool is_disk_full(const std::exception& e);

/// What a coordinator's stored state survives.
enum class Durability {
  machine,  ///< A power cut: what is acknowledged was flushed to the disk first (fsync). `tessera serve`'s default.
  process,  ///< A crash of the process only: nothing is flushed (the page cache keeps every write).
  none,     ///< Nothing: jobs, tiles and leases are kept in memory and a restart forgets them (merged results and
            ///< blobs are still files, never flushed). For a coordinator that dies with the command that started it
            ///< (`render --workers`).
};

/// How a file written under `durability` is flushed (write_file_atomic).
constexpr Flush flush_for(Durability durability) {
  return durability == Durability::machine ? Flush::to_disk : Flush::none;
}

/// Outcome of storing a blob.
struct PutBlobResult {
  enum Status { created, existed, mismatch } status = created;  ///< mismatch: the bytes hash to `actual`.
  std::string actual;  ///< SHA-256 of the bytes (hex).
  uint64_t size = 0;   ///< Byte count.
};

/// Immutable blobs addressed by the SHA-256 of their bytes.
class BlobStore {
 public:
  virtual ~BlobStore() = default;
  /// Stores bytes under `sha256` (64 lowercase hex) after checking they hash to it; repeats are cheap no-ops.
  virtual PutBlobResult put(const std::string& sha256, std::string_view bytes) = 0;
  /// True when the blob is stored.
  virtual bool has(const std::string& sha256) = 0;
  /// A readable file holding the blob, or nothing when it is not stored.
  virtual std::optional<std::filesystem::path> file(const std::string& sha256) = 0;
  /// Marks a stored blob as just used (a client checked or uploaded it), which keeps it for the collector's grace
  /// period; false when it is not stored.
  virtual bool touch(const std::string& sha256) = 0;
  /// Every stored blob with the time it was last stored or touched (ms since the Unix epoch); throws StorageError.
  virtual std::vector<std::pair<std::string, int64_t>> list() = 0;
  /// Deletes a blob (nothing happens when it is not stored); throws StorageError.
  virtual void remove(const std::string& sha256) = 0;
};

/// Where the coordinator with data folder `data_dir` keeps its blobs (a DiskBlobStore's folder): DATA_DIR/blobs.
std::filesystem::path blobs_dir(const std::filesystem::path& data_dir);

/// The file of the blob `sha256` in a DiskBlobStore rooted at `dir`: DIR/<first 2 hex digits>/<sha256>. A file put
/// there whole (e.g. a hard link to a verified copy) is a stored blob for the store.
std::filesystem::path blob_file(const std::filesystem::path& dir, const std::string& sha256);

/// Blobs as files DIR/<2 hex>/<64 hex>, written to a temp file, fsynced (Durability::machine) and renamed into place.
class DiskBlobStore final : public BlobStore {
 public:
  /// A store rooted at `dir` (created if missing, temp files of interrupted writes removed); throws StorageError when
  /// it cannot be created or cleaned.
  explicit DiskBlobStore(std::filesystem::path dir, Durability durability = Durability::machine);
  /// How many temp files of interrupted writes the constructor removed.
  size_t leftovers_removed() const { return leftovers_removed_; }
  PutBlobResult put(const std::string& sha256, std::string_view bytes) override;
  bool has(const std::string& sha256) override;
  std::optional<std::filesystem::path> file(const std::string& sha256) override;
  bool touch(const std::string& sha256) override;
  std::vector<std::pair<std::string, int64_t>> list() override;
  void remove(const std::string& sha256) override;

 private:
  std::filesystem::path path_of(const std::string& sha256) const { return blob_file(dir_, sha256); }
  std::filesystem::path dir_;
  Durability durability_;
  size_t leftovers_removed_ = 0;
};

/// Job records (the submitted spec and derived facts) and job outputs.
class JobStore {
 public:
  virtual ~JobStore() = default;
  /// Durably stores a job's record, replacing an older one; throws StorageError.
  virtual void save_record(const std::string& job, const nlohmann::json& record) = 0;
  /// Durably stores several jobs' records at once (a sequence's frames), each given as its JSON text, all or none;
  /// throws StorageError.
  virtual void save_record_texts(const std::vector<std::pair<std::string, std::string>>& records) {
    for (const auto& [job, text] : records) save_record(job, nlohmann::json::parse(text));
  }
  /// The job's record, or nothing when there is none; throws StorageError on unreadable records.
  virtual std::optional<nlohmann::json> load_record(const std::string& job) = 0;
  /// Where the job's merged image is.
  virtual std::filesystem::path result_path(const std::string& job) = 0;
  /// Writes the job's merged image atomically: `write` fills a temp file beside result_path, which is then flushed to
  /// the disk (as durably as the store keeps its state) and renamed over it; on failure (what `write` throws, or
  /// StorageError) nothing is left and the old result stays.
  virtual void write_result(const std::string& job, const std::function<void(const std::filesystem::path&)>& write) = 0;
  /// A folder for short-lived files (uploads being validated) on the same file system.
  virtual std::filesystem::path scratch_dir() = 0;
  /// The stored pixels of the job's done tiles as (tile number, float32 RGB rows); throws StorageError.
  virtual std::vector<std::pair<int64_t, std::string>> tile_pixels(const std::string& job) = 0;
  /// Stores a resumable job's tile as uploaded at `spp` (an EXR with its exact sums, server/tile_state.h), replacing
  /// the tile's earlier one; throws StorageError.
  virtual void save_tile_state(const std::string& job, int64_t tile, uint32_t spp, std::string_view exr) = 0;
  /// The spp of the tile's stored state, or nothing when it has none; throws StorageError.
  virtual std::optional<uint32_t> tile_state_spp(const std::string& job, int64_t tile) = 0;
  /// The tile's stored state as (spp, EXR bytes), or nothing; throws StorageError.
  virtual std::optional<std::pair<uint32_t, std::string>> tile_state(const std::string& job, int64_t tile) = 0;
  /// Deletes the job's outputs (its result file); throws StorageError.
  virtual void remove_outputs(const std::string& job) = 0;
  /// The jobs that have outputs on disk; throws StorageError.
  virtual std::vector<std::string> jobs_with_outputs() = 0;
};

/// Creates a folder and its parents; throws StorageError naming it.
void make_dirs(const std::filesystem::path& dir);

/// Removes the temp files (names ending in ".tmp") that writes interrupted by a crash left anywhere below `dir`, and,
/// when `everything` is true, every other entry below it too; at start-up only (a running write's temp file would
/// go). Returns how many entries it removed; throws StorageError when one cannot be removed.
size_t remove_leftovers(const std::filesystem::path& dir, bool everything = false);

}  // namespace tessera::server
