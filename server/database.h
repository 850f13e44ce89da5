// The coordinator's durable state in one SQLite file (WAL): a small RAII wrapper over the C API and the store that keeps
// jobs, tiles, leases, workers and job records in it, and done tiles' pixels in a file per job beside it.
#pragma once

#include "server/coordinator_store.h"
#include "server/group_commit.h"
#include "server/pixel_files.h"
#include "server/scheduler_store.h"
#include "server/storage.h"
#include "server/wal_checkpointer.h"
#include "server/webhook_log.h"

#include <cstdint>
#include <filesystem>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

struct sqlite3;
struct sqlite3_stmt;

namespace tessera::server {

/// One prepared statement of a Database; reset and its bindings cleared whenever it is handed out again.
class Statement {
 public:
  /// Wraps a prepared statement of `db`; `sql` is kept for error messages.
  Statement(sqlite3* db, sqlite3_stmt* stmt, std::string sql);
  ~Statement();
  Statement(const Statement&) = delete;
  Statement& operator=(const Statement&) = delete;

  /// Binds an integer to parameter `i` (1-based).
  Statement& bind(int i, int64_t v);
  /// Binds text (copied) to parameter `i`.
  Statement& bind_text(int i, std::string_view v);
  /// Binds a blob (copied) to parameter `i`.
  Statement& bind_blob(int i, std::string_view v);
  /// Binds a blob to parameter `i` without copying it: the bytes must stay valid until the statement has run.
  Statement& bind_blob_uncopied(int i, std::string_view v);
  /// Binds NULL to parameter `i`.
  Statement& bind_null(int i);
  /// Binds an integer or NULL.
  Statement& bind(int i, const std::optional<int64_t>& v) { return v ? bind(i, *v) : bind_null(i); }
  /// Steps once: true when a row is available; throws StorageError with the SQL on errors.
  bool step();
  /// Steps to completion (for statements that return no rows).
  void run();
  /// Column `i` (0-based) of the current row as an integer.
  int64_t integer(int i) const;
  /// Column `i` as text ("" for NULL).
  std::string text(int i) const;
  /// Column `i` as bytes ("" for NULL).
  std::string blob(int i) const;
  /// True when column `i` is NULL.
  bool is_null(int i) const;
  /// Resets the statement and clears its bindings.
  void reset();

 private:
  sqlite3* db_;
  sqlite3_stmt* stmt_;
  std::string sql_;
};

/// An open SQLite database file. Not thread-safe: callers serialize access.
class Database {
 public:
  /// Opens (creating if missing) `file` in WAL mode with a busy timeout and `synchronous` (SQLite's PRAGMA value:
  /// "FULL", "NORMAL" or "OFF"), set before the file is switched to WAL so that making it waits for the disk only
  /// as that mode says; throws StorageError.
  explicit Database(const std::filesystem::path& file, const char* synchronous = "FULL");
  ~Database();
  Database(const Database&) = delete;
  Database& operator=(const Database&) = delete;

  /// Runs one or more statements without results; throws StorageError naming the SQL.
  void exec(const std::string& sql);
  /// The cached prepared statement for `sql`, reset and unbound.
  Statement& statement(const std::string& sql);
  /// Rows changed by the last INSERT, UPDATE or DELETE.
  int64_t changes() const;
  /// Calls `hook` after each commit with the frames now in the write-ahead log, instead of SQLite's own checkpoint
  /// after commits (so a WalCheckpointer can run them elsewhere).
  void on_commit(std::function<void(int frames)> hook);
  /// The file it was opened from.
  const std::filesystem::path& file() const { return file_; }

 private:
  std::filesystem::path file_;
  sqlite3* db_ = nullptr;
  std::map<std::string, std::unique_ptr<Statement>> cache_;
  std::function<void(int)> commit_hook_;
};

/// BEGIN IMMEDIATE ... COMMIT; rolls back when destroyed uncommitted.
class Transaction {
 public:
  /// Begins a write transaction on `db`.
  explicit Transaction(Database& db);
  ~Transaction();
  Transaction(const Transaction&) = delete;
  Transaction& operator=(const Transaction&) = delete;
  /// Commits; when it returns, the transaction is durable.
  void commit();

 private:
  Database& db_;
  bool done_ = false;
};

/// The coordinator's state under DIR: DIR/tessera.db holds jobs, tiles, leases, workers and job records, DIR/pixels/
/// the done tiles' pixels (a file per job, each tile's row naming where its bytes are: server/pixel_files.h),
/// DIR/jobs/<id>/ the merged results, DIR/tmp/ scratch files. Thread-safe (one connection behind a mutex). The database runs with
/// auto_vacuum=INCREMENTAL: a change that purges jobs hands their pages back and truncates the write-ahead log.
/// A write that fails for want of space (DiskFullError) stops every later write, which fails the same way at once,
/// until make_room() has copied the write-ahead log into the database file and cut the log to nothing: the space
/// freed on the disk then goes to the database, not to a log that grows into it again.
class DurableStore final : public CoordinatorStore, public WebhookLog {
 public:
  /// The database's file name in the store's folder.
  static constexpr const char* kFileName = "tessera.db";
  /// The schema version this build reads and writes (version 2: a done tile's pixels may be in its job's pixel file).
  /// A file of version 1 is upgraded when opened.
  static constexpr int kSchemaVersion = 2;
  /// The folder of the pixel files in the store's folder.
  static constexpr const char* kPixelsDir = "pixels";
  /// Frames (4 KiB pages) in the write-ahead log that start a checkpoint (SQLite's own default).
  static constexpr int kCheckpointFrames = 1000;
  /// Ids reserved ahead by each write of the id sequence.
  static constexpr uint64_t kIdBlock = 1024;

  /// Opens or creates the store under `dir`, removing what a crash can leave behind: every file in DIR/tmp/, the
  /// temp files of interrupted result writes under DIR/jobs/ and the pixel files of jobs it no longer holds (at
  /// load()). Throws StorageError (unreadable file, newer schema).
  explicit DurableStore(const std::filesystem::path& dir, Durability durability = Durability::machine);
  ~DurableStore() override;

  void apply(const SchedulerChanges& changes) override;
  std::vector<DueDelivery> due_deliveries(int64_t now, size_t limit, const std::set<std::string>& skip) override;
  void record_attempt(const std::string& id, const std::string& url, const DeliveryAttempt& attempt) override;
  std::vector<protocol::WebhookDelivery> deliveries(size_t limit) override;
  /// Every row. A done tile whose bytes its job's pixel file does not hold intact (the machine stopped after the row
  /// reached the disk but before its bytes did, so the tile was never acknowledged) is pending again, and a done job
  /// of it running again, each with a warning; the repair is stored.
  SchedulerSnapshot load() override;
  /// Commits run with synchronous=NORMAL (safe against a process crash); with Durability::machine this waits for an
  /// fdatasync of the pixel files written since the last flush, then of the write-ahead log, which makes them safe
  /// against a power cut. The flush is a group commit (one
  /// thread, one fdatasync for every caller that arrived while the previous one ran). A failed flush aborts the
  /// process (the page cache can no longer be trusted; a restart recovers from what is on disk). With
  /// Durability::process nothing is flushed.
  void sync() override;
  /// As sync(), but `then` runs (on the flushing thread) once the flush is done, and the caller does not wait.
  void sync_async(std::function<void()> then) override;

  void save_record(const std::string& job, const nlohmann::json& record) override;
  void save_record_texts(const std::vector<std::pair<std::string, std::string>>& records) override;
  std::optional<nlohmann::json> load_record(const std::string& job) override;
  std::vector<std::pair<int64_t, std::string>> tile_pixels(const std::string& job) override;
  void save_tile_state(const std::string& job, int64_t tile, uint32_t spp, std::string_view exr) override;
  std::optional<uint32_t> tile_state_spp(const std::string& job, int64_t tile) override;
  std::optional<std::pair<uint32_t, std::string>> tile_state(const std::string& job, int64_t tile) override;

  /// The database file.
  std::filesystem::path database_file() const { return db_.file(); }
  void append_audit(const protocol::AuditEntry& entry) override;
  protocol::AuditList audit(const protocol::AuditQuery& query) override;
  int64_t forget_audit(int64_t before_ms) override;
  size_t leftovers_removed() const override { return leftovers_removed_; }
  std::string where() const override { return database_file().string(); }
  bool make_room() override;
  std::optional<StoreStats> stats() const override;
  /// Flushes of the write-ahead log and acknowledgements that waited for them, so far.
  GroupCommitStats flushes() { return group_.stats(); }

 private:
  // apply() with mu_ held; each pixel file it appends to is noted in `appended` with its size before the change.
  void apply_locked(const SchedulerChanges& changes, std::vector<std::pair<std::string, int64_t>>& appended);
  void give_back_free_pages();  // after a purge: shrink the file and the log (mu_ held)
  void flush_log();             // fdatasync of the pixel files, then of the write-ahead log, on the group commit's thread
  void upgrade_tiles();         // a version-1 tiles table gains the pixel file's columns in its CHECK (in a transaction)
  template <class F>
  void write_locked(F&& write);  // runs a write (mu_ held) unless the disk was full, noting when it is (full_)
  std::mutex mu_;
  bool full_ = false;  // a write failed for want of space and make_room() has not succeeded since (mu_)
  CounterRow written_counters_;  // as the meta table holds them, next_seq the reserved bound (mu_)
  struct LogFile {
    int fd = -1;
    ~LogFile();
  };
  mutable std::mutex stats_mu_;  // guards stats_
  StoreStats stats_;
  std::mutex wal_mu_;   // guards wal_fd_
  LogFile wal_fd_;      // the write-ahead log, opened for flush_log() (closed after group_ has stopped)
  size_t leftovers_removed_ = 0;
  PixelFiles pixels_;   // done tiles' bytes (appended with mu_ held; flushed by flush_log)
  Database db_;
  std::unique_ptr<WalCheckpointer> checkpointer_;  // checkpoints db_'s log (stopped before db_ closes)
  GroupCommit group_;   // last: its thread flushes the log of db_
};

}  // namespace tessera::server
