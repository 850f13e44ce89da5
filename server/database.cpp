#include "server/database.h"

#include "failpoint/failpoint.h"

#include <sqlite3.h>
#include <spdlog/spdlog.h>

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <limits>
#include <set>
#include <tuple>
#include <cerrno>
#include <cstdlib>
#include <cstring>
#include <stdexcept>

namespace fs = std::filesystem;
using nlohmann::json;

namespace tessera::server {

namespace {

// The first line of a statement, for error messages.
std::string sql_head(const std::string& sql) {
  std::string s = sql.substr(0, std::min(sql.find('\n'), size_t(120)));
  if (s.size() == 120) s.replace(117, 3, "...");
  return s;
}

// `rc` is the failed call's result: SQLITE_FULL (the disk has no room for the database or its log) is a DiskFullError.
[[noreturn]] void fail(sqlite3* db, const std::string& what, int rc = SQLITE_ERROR) {
  const std::string text = what + ": " + (db ? sqlite3_errmsg(db) : "out of memory");
  if ((rc & 0xff) == SQLITE_FULL) throw DiskFullError(text);
  throw StorageError(text);
}

json map_json(const std::map<std::string, std::string>& m) { return json(m); }

template <class T>
std::map<std::string, T> json_map(const std::string& text, const char* what) {
  try {
    return json::parse(text).get<std::map<std::string, T>>();
  } catch (const json::exception& e) {
    throw StorageError(std::string("stored ") + what + " is not a JSON object: " + e.what());
  }
}

// A stored JSON list of strings; `what` names it in the error ("job j-1: stored workers").
std::vector<std::string> json_list(const std::string& text, const std::string& what) {
  try {
    return json::parse(text).get<std::vector<std::string>>();
  } catch (const json::exception& e) {
    throw StorageError(what + " is not a JSON list: " + e.what());
  }
}

// The schema as version 1 made it; kAddedColumns and upgrade_tiles() bring it to the current version. A tile can only
// be done with its pixels, the bytes themselves (version 1) or where they are in its job's pixel file: the database
// itself refuses anything else.
constexpr const char* kSchema = R"sql(
CREATE TABLE IF NOT EXISTS meta(key TEXT PRIMARY KEY, value INTEGER NOT NULL);
CREATE TABLE IF NOT EXISTS jobs(
  id TEXT PRIMARY KEY, seq INTEGER NOT NULL, name TEXT NOT NULL, priority INTEGER NOT NULL,
  width INTEGER NOT NULL, height INTEGER NOT NULL, tile_size INTEGER NOT NULL, spp INTEGER NOT NULL,
  seed INTEGER NOT NULL, scene_hash TEXT NOT NULL, state TEXT NOT NULL, created_ms INTEGER NOT NULL,
  started_ms INTEGER, finished_ms INTEGER, error TEXT, rays INTEGER NOT NULL, workers TEXT NOT NULL,
  worker_failures TEXT NOT NULL, worker_last_error TEXT NOT NULL);
CREATE TABLE IF NOT EXISTS tiles(
  job TEXT NOT NULL REFERENCES jobs(id), idx INTEGER NOT NULL, state TEXT NOT NULL, lease TEXT NOT NULL,
  failures TEXT NOT NULL, pixels BLOB,
  PRIMARY KEY(job, idx),
  CHECK(state <> 'done' OR pixels IS NOT NULL));
CREATE TABLE IF NOT EXISTS leases(
  id TEXT PRIMARY KEY, job TEXT NOT NULL REFERENCES jobs(id), tile INTEGER NOT NULL, worker TEXT NOT NULL,
  deadline_ms INTEGER NOT NULL, state TEXT NOT NULL);
CREATE TABLE IF NOT EXISTS workers(id TEXT PRIMARY KEY, name TEXT NOT NULL);
CREATE TABLE IF NOT EXISTS job_records(id TEXT PRIMARY KEY, record TEXT NOT NULL);
CREATE TABLE IF NOT EXISTS tile_states(job TEXT NOT NULL, idx INTEGER NOT NULL, spp INTEGER NOT NULL, exr BLOB NOT NULL,
  PRIMARY KEY(job, idx));
-- A job's workers, one row each (a build before this table kept the whole list in jobs.workers, rewritten with
-- every change of the job; such a list comes first, and a build of that kind reading this file sees only it).
CREATE TABLE IF NOT EXISTS job_workers(job TEXT NOT NULL, idx INTEGER NOT NULL, worker TEXT NOT NULL,
  PRIMARY KEY(job, idx));
-- The audit trail: every control action, who took it and from where.
CREATE TABLE IF NOT EXISTS audit(id INTEGER PRIMARY KEY AUTOINCREMENT, at_ms INTEGER NOT NULL, user TEXT NOT NULL,
  role TEXT NOT NULL, action TEXT NOT NULL, target TEXT NOT NULL, address TEXT NOT NULL, status INTEGER NOT NULL);
CREATE INDEX IF NOT EXISTS audit_at ON audit(at_ms);
-- The webhook outbox (server/outbox.h): a row per event and destination, written with the change that caused the
-- event, then updated by each delivery attempt.
CREATE TABLE IF NOT EXISTS webhook_outbox(id TEXT NOT NULL, url TEXT NOT NULL, event TEXT NOT NULL, job TEXT NOT NULL,
  created_ms INTEGER NOT NULL, body TEXT NOT NULL, state TEXT NOT NULL DEFAULT 'pending',
  attempts INTEGER NOT NULL DEFAULT 0, next_ms INTEGER NOT NULL DEFAULT 0, last_status INTEGER, last_error TEXT,
  PRIMARY KEY(id, url));
-- Due deliveries are looked up address by address (DurableStore::due_deliveries), so that the many pending rows of
-- an address the sender skips are never read; the index by (state, next_ms) alone that a file may hold from before
-- serves no query and is dropped.
CREATE INDEX IF NOT EXISTS webhook_outbox_url_due ON webhook_outbox(state, url, next_ms);
DROP INDEX IF EXISTS webhook_outbox_due;
)sql";

// Columns added after version 1 was released: older files gain them with these defaults (the schema version stays
// for those a version-1 reader can ignore without contradicting them).
struct AddedColumn {
  const char* table;
  const char* column;
  const char* declaration;
};
constexpr AddedColumn kAddedColumns[] = {
    {"tiles", "attempts", "INTEGER NOT NULL DEFAULT 0"},
    {"tiles", "render_ms", "INTEGER NOT NULL DEFAULT -1"},
    {"tiles", "rays", "INTEGER NOT NULL DEFAULT 0"},
    {"tiles", "logs", "TEXT NOT NULL DEFAULT '{}'"},
    {"tiles", "rendered_by", "TEXT NOT NULL DEFAULT ''"},
    // A done tile's log (sent with its upload), or that it was not kept.
    {"tiles", "log", "TEXT NOT NULL DEFAULT '[]'"},
    {"tiles", "log_not_kept", "INTEGER NOT NULL DEFAULT 0"},
    {"leases", "granted_ms", "INTEGER NOT NULL DEFAULT 0"},
    {"jobs", "tile_timeout_s", "INTEGER NOT NULL DEFAULT 3600"},
    {"workers", "drained", "INTEGER NOT NULL DEFAULT 0"},
    {"workers", "secret_sha256", "TEXT NOT NULL DEFAULT ''"},
    // Sequences: a sequence's row counts its frames; each frame's row names its sequence and number.
    {"jobs", "frame_total", "INTEGER NOT NULL DEFAULT 0"},
    {"jobs", "frame_order", "TEXT NOT NULL DEFAULT 'in_order'"},
    {"jobs", "sequence", "TEXT NOT NULL DEFAULT ''"},
    {"jobs", "frame", "INTEGER NOT NULL DEFAULT 0"},
    // A shared farm: who submitted a job, the worker tags it needs and its cap; the tags each worker offers.
    {"jobs", "owner", "TEXT NOT NULL DEFAULT ''"},
    {"jobs", "require", "TEXT NOT NULL DEFAULT '[]'"},
    {"jobs", "max_workers", "INTEGER NOT NULL DEFAULT 0"},
    {"workers", "tags", "TEXT NOT NULL DEFAULT '[]'"},
    // Pipelines: a job's dependencies, steps and webhook as the JSON object of protocol/pipeline.h.
    {"jobs", "pipeline", "TEXT NOT NULL DEFAULT '{}'"},
    // Version 2: a done tile's bytes in its job's pixel file (server/tile_pixel_file.h), NULL for a tile whose bytes
    // are in `pixels` (stored by version 1) or that has none.
    {"tiles", "pixel_offset", "INTEGER"},
    {"tiles", "pixel_length", "INTEGER"},
    {"tiles", "pixel_checksum", "INTEGER"},
};

// The tiles table's CHECK as version 1 made it, and as version 2 has it.
constexpr const char* kDoneCheckV1 = "CHECK(state <> 'done' OR pixels IS NOT NULL)";
constexpr const char* kDoneCheck = "CHECK(state <> 'done' OR pixels IS NOT NULL OR pixel_length IS NOT NULL)";

std::string tile_name(const std::string& job, int64_t tile) { return "job " + job + " tile " + std::to_string(tile); }

}  // namespace

// ---- Statement

Statement::Statement(sqlite3* db, sqlite3_stmt* stmt, std::string sql) : db_(db), stmt_(stmt), sql_(std::move(sql)) {}

Statement::~Statement() { sqlite3_finalize(stmt_); }

Statement& Statement::bind(int i, int64_t v) {
  if (sqlite3_bind_int64(stmt_, i, v) != SQLITE_OK) fail(db_, "binding parameter " + std::to_string(i) + " of '" + sql_head(sql_) + "'");
  return *this;
}

Statement& Statement::bind_text(int i, std::string_view v) {
  if (sqlite3_bind_text64(stmt_, i, v.data(), v.size(), SQLITE_TRANSIENT, SQLITE_UTF8) != SQLITE_OK)
    fail(db_, "binding parameter " + std::to_string(i) + " of '" + sql_head(sql_) + "'");
  return *this;
}

Statement& Statement::bind_blob(int i, std::string_view v) {
  // A zero-length blob must still be a blob, not NULL: bind a non-null pointer.
  static const char empty = 0;
  if (sqlite3_bind_blob64(stmt_, i, v.empty() ? &empty : v.data(), v.size(), SQLITE_TRANSIENT) != SQLITE_OK)
    fail(db_, "binding parameter " + std::to_string(i) + " of '" + sql_head(sql_) + "'");
  return *this;
}

Statement& Statement::bind_blob_uncopied(int i, std::string_view v) {
  static const char empty = 0;
  if (sqlite3_bind_blob64(stmt_, i, v.empty() ? &empty : v.data(), v.size(), SQLITE_STATIC) != SQLITE_OK)
    fail(db_, "binding parameter " + std::to_string(i) + " of '" + sql_head(sql_) + "'");
  return *this;
}

Statement& Statement::bind_null(int i) {
  if (sqlite3_bind_null(stmt_, i) != SQLITE_OK) fail(db_, "binding parameter " + std::to_string(i) + " of '" + sql_head(sql_) + "'");
  return *this;
}

bool Statement::step() {
  const int rc = sqlite3_step(stmt_);
  if (rc == SQLITE_ROW) return true;
  if (rc == SQLITE_DONE) return false;
  std::string what = "running '";  // built by appending: GCC 12 flags "'" + string as an overlapping copy
  what += sql_head(sql_);
  what += "'";
  sqlite3_reset(stmt_);
  fail(db_, what, rc);
}

void Statement::run() {
  while (step()) {
  }
}

int64_t Statement::integer(int i) const { return sqlite3_column_int64(stmt_, i); }

std::string Statement::text(int i) const {
  const auto* p = reinterpret_cast<const char*>(sqlite3_column_text(stmt_, i));
  return p ? std::string(p, size_t(sqlite3_column_bytes(stmt_, i))) : std::string();
}

std::string Statement::blob(int i) const {
  const void* p = sqlite3_column_blob(stmt_, i);
  return p ? std::string(static_cast<const char*>(p), size_t(sqlite3_column_bytes(stmt_, i))) : std::string();
}

bool Statement::is_null(int i) const { return sqlite3_column_type(stmt_, i) == SQLITE_NULL; }

void Statement::reset() {
  sqlite3_reset(stmt_);
  sqlite3_clear_bindings(stmt_);
}

// ---- Database

Database::Database(const fs::path& file, const char* synchronous) : file_(file) {
  const int rc = sqlite3_open_v2(file.c_str(), &db_, SQLITE_OPEN_READWRITE | SQLITE_OPEN_CREATE | SQLITE_OPEN_NOMUTEX, nullptr);
  if (rc != SQLITE_OK) {
    const std::string why = db_ ? sqlite3_errmsg(db_) : sqlite3_errstr(rc);
    sqlite3_close(db_);
    db_ = nullptr;
    throw StorageError("cannot open database " + file.string() + ": " + why);
  }
  try {
    sqlite3_busy_timeout(db_, 10'000);
    exec(std::string("PRAGMA synchronous=") + synchronous);
    exec("PRAGMA journal_mode=WAL");
    exec("PRAGMA foreign_keys=ON");
  } catch (...) {
    sqlite3_close(db_);
    throw;
  }
}

Database::~Database() {
  cache_.clear();  // statements before the connection
  sqlite3_close(db_);
}

void Database::exec(const std::string& sql) {
  char* err = nullptr;
  if (const int rc = sqlite3_exec(db_, sql.c_str(), nullptr, nullptr, &err); rc != SQLITE_OK) {
    const std::string why = err ? err : sqlite3_errmsg(db_);
    sqlite3_free(err);
    const std::string text = file_.string() + ": '" + sql_head(sql) + "': " + why;
    if ((rc & 0xff) == SQLITE_FULL) throw DiskFullError(text);
    throw StorageError(text);
  }
}

Statement& Database::statement(const std::string& sql) {
  auto& slot = cache_[sql];
  if (!slot) {
    sqlite3_stmt* stmt = nullptr;
    if (sqlite3_prepare_v3(db_, sql.c_str(), int(sql.size()), SQLITE_PREPARE_PERSISTENT, &stmt, nullptr) != SQLITE_OK) {
      cache_.erase(sql);
      fail(db_, file_.string() + ": preparing '" + sql_head(sql) + "'");
    }
    slot = std::make_unique<Statement>(db_, stmt, sql);
  }
  slot->reset();
  return *slot;
}

int64_t Database::changes() const { return sqlite3_changes64(db_); }

void Database::on_commit(std::function<void(int frames)> hook) {
  commit_hook_ = std::move(hook);
  sqlite3_wal_hook(
      db_,
      [](void* self, sqlite3*, const char*, int frames) {
        static_cast<Database*>(self)->commit_hook_(frames);
        return SQLITE_OK;
      },
      this);
}

// BEGIN, COMMIT and ROLLBACK are prepared once and kept (every lease and every tile is a transaction; sqlite3_exec
// would parse them each time).
Transaction::Transaction(Database& db) : db_(db) { db_.statement("BEGIN IMMEDIATE").run(); }

Transaction::~Transaction() {
  if (done_) return;
  try {
    db_.statement("ROLLBACK").run();
  } catch (...) {
    // Nothing more to do: SQLite rolls back an open transaction when the connection closes.
  }
}

void Transaction::commit() {
  db_.statement("COMMIT").run();
  done_ = true;
}

// ---- DurableStore

DurableStore::DurableStore(const fs::path& dir, Durability durability)
    : CoordinatorStore(dir, durability),
      pixels_(dir / kPixelsDir, durability == Durability::machine),  // flushed by the group commit, as the log is
      // Commits survive a process crash without waiting for the disk; sync() makes them survive a power cut when the
      // scheduler acknowledges something, outside its lock (see SchedulerStore::sync). A store that only has to
      // survive the process lets SQLite skip its own flushes too (at checkpoints and when the file is made).
      db_((make_dirs(dir), dir / kFileName), durability == Durability::machine ? "NORMAL" : "OFF"),
      group_([this] { flush_log(); }) {
  // Uploads being validated and results being written when the last run was killed.
  leftovers_removed_ = remove_leftovers(scratch_, true) + remove_leftovers(jobs_dir_);
  // Purged jobs' pages are returned to the file system (see give_back_free_pages). The mode is set before the first
  // table is created; a database made by an older build is rewritten once (VACUUM) to switch to it.
  Statement& mode = db_.statement("PRAGMA auto_vacuum");
  const int64_t auto_vacuum = mode.step() ? mode.integer(0) : 0;
  mode.reset();
  if (auto_vacuum != 2) {
    db_.exec("PRAGMA auto_vacuum=INCREMENTAL");
    db_.exec("VACUUM");
  }
  Transaction tx(db_);
  db_.exec(kSchema);
  for (const AddedColumn& c : kAddedColumns) {
    Statement& has = db_.statement(std::string("SELECT count(*) FROM pragma_table_info('") + c.table + "') WHERE name = ?");
    has.bind_text(1, c.column);
    const bool present = has.step() && has.integer(0) > 0;
    has.reset();
    if (!present) db_.exec(std::string("ALTER TABLE ") + c.table + " ADD COLUMN " + c.column + " " + c.declaration);
  }
  Statement& get = db_.statement("SELECT value FROM meta WHERE key = 'schema_version'");
  const std::optional<int64_t> version = get.step() ? std::optional<int64_t>(get.integer(0)) : std::nullopt;
  get.reset();
  if (version && *version != kSchemaVersion && *version != 1)
    throw StorageError(db_.file().string() + " has schema version " + std::to_string(*version) +
                       "; this build reads versions 1 and " + std::to_string(kSchemaVersion));
  upgrade_tiles();
  db_.statement("INSERT OR REPLACE INTO meta(key, value) VALUES('schema_version', ?)").bind(1, int64_t(kSchemaVersion)).run();
  tx.commit();
  // From here on the log is checkpointed by a thread of its own, never inside a commit.
  checkpointer_ = std::make_unique<WalCheckpointer>(
      db_.file(), durability_ == Durability::machine, kCheckpointFrames,
      [this](const std::function<void()>& checkpoint) {
        std::lock_guard lock(mu_);
        checkpoint();
      });
  db_.on_commit([this](int frames) {
    const int written = checkpointer_->committed(frames);
    std::lock_guard lock(stats_mu_);
    stats_.log_pages += uint64_t(written);
  });
}

std::optional<StoreStats> DurableStore::stats() const {
  std::lock_guard lock(stats_mu_);
  return stats_;
}

void DurableStore::upgrade_tiles() {
  Statement& get = db_.statement("SELECT sql FROM sqlite_master WHERE type = 'table' AND name = 'tiles'");
  std::string sql = get.step() ? get.text(0) : "";
  get.reset();
  const size_t check = sql.find(kDoneCheckV1);
  if (check == std::string::npos) return;
  // SQLite cannot change a CHECK in place: the table is made again under its own definition with the new CHECK, its
  // rows copied (pixels stored by version 1 stay where they are), and it takes the old one's place.
  sql.replace(check, std::strlen(kDoneCheckV1), kDoneCheck);
  const size_t open = sql.find('(');  // after CREATE TABLE tiles, its name quoted or not
  if (open == std::string::npos || sql.find("tiles") > open)
    throw StorageError(db_.file().string() + ": the tiles table's definition is not one this build knows: " + sql_head(sql));
  sql.replace(0, open, "CREATE TABLE tiles_v2");
  db_.exec(sql);
  db_.exec("INSERT INTO tiles_v2 SELECT * FROM tiles");
  db_.exec("DROP TABLE tiles");
  db_.exec("ALTER TABLE tiles_v2 RENAME TO tiles");
}

DurableStore::~DurableStore() = default;  // group_, then checkpointer_, then db_ (the connection's last checkpoint)

DurableStore::LogFile::~LogFile() {
  if (fd >= 0) ::close(fd);
}

void DurableStore::sync() {
  if (durability_ == Durability::process) return;
  group_.flush();
}

void DurableStore::sync_async(std::function<void()> then) {
  if (durability_ == Durability::process) return then();
  group_.after_flush(std::move(then));
}

void DurableStore::flush_log() {
  int fd = -1;
  {
    std::lock_guard lock(wal_mu_);
    struct stat st {};
    if (wal_fd_.fd >= 0 && (::fstat(wal_fd_.fd, &st) != 0 || st.st_nlink == 0)) {  // the log was removed and made anew
      ::close(wal_fd_.fd);
      wal_fd_.fd = -1;
    }
    if (wal_fd_.fd < 0) wal_fd_.fd = ::open((db_.file().string() + "-wal").c_str(), O_RDONLY | O_CLOEXEC);
    fd = wal_fd_.fd;
  }
  bool flush_fails = false;  // set by tests to take the failure path below
  TESSERA_FAIL_POINT_RETURN("store.sync", [&](const std::string&) { flush_fails = true; });
  // After a failed flush the kernel may have dropped the dirty pages, so retrying cannot tell whether they reached
  // the disk: stop, and let a restart recover from what the disk holds (acknowledged results were never acknowledged;
  // a tile whose row reached the disk without its bytes is pending again, see load()). The disk being full cannot
  // fail a pixel file's flush: its space was allocated when the bytes were written.
  std::vector<fs::path> purged;
  const auto start = std::chrono::steady_clock::now();
  try {
    // The tiles' bytes first: a row that names them is never on the disk before they are.
    purged = pixels_.sync_written();
  } catch (const StorageError& e) {
    spdlog::critical("{}; stopping the coordinator", e.what());
    std::abort();
  }
  // No lock held during the flush: concurrent callers wait for the same disk write instead of queueing behind a mutex.
  if (fd >= 0 && !flush_fails && ::fdatasync(fd) == 0) {
    {
      std::lock_guard lock(stats_mu_);
      stats_.flushes.observe(std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count());
    }
    try {
      PixelFiles::delete_files(purged);  // the rows that named them are gone for good now
    } catch (const StorageError& e) {
      spdlog::warn("{} (removed when the coordinator next starts)", e.what());
    }
    return;
  }
  const int err = flush_fails ? EIO : errno;
  spdlog::critical("cannot flush {}-wal to disk ({}); stopping the coordinator", db_.file().string(),
                   fd < 0 ? "cannot open it" : std::strerror(err));
  std::abort();
}

template <class F>
void DurableStore::write_locked(F&& write) {
  if (full_)
    throw DiskFullError(db_.file().string() +
                        ": the disk was full at an earlier write; no write until its log is checkpointed");
  try {
    write();
  } catch (const DiskFullError&) {
    full_ = true;
    throw;
  }
}

bool DurableStore::make_room() {
  std::lock_guard lock(mu_);
  if (!full_) return true;
  // The failed transaction was rolled back, so this connection holds no snapshot: the checkpoint can copy the whole
  // log, which needs room only for the pages the database file does not have yet, and then cuts the log to nothing.
  std::string why;  // the disk is still full: said by the caller, which tries again
  if (!checkpointer_->truncate(&why)) return false;
  full_ = false;
  return true;
}

void DurableStore::apply(const SchedulerChanges& c) {
  std::lock_guard lock(mu_);
  write_locked([&] {
    // Pixel files appended to by this change, with their sizes before it: cut back when the change is not stored.
    std::vector<std::pair<std::string, int64_t>> appended;
    try {
      apply_locked(c, appended);
    } catch (...) {
      for (auto it = appended.rbegin(); it != appended.rend(); ++it) {
        try {
          pixels_.cut(it->first, it->second);
        } catch (const StorageError& e) {
          spdlog::warn("{} (its unnamed bytes stay until the job is deleted)", e.what());
        }
      }
      throw;
    }
  });
}

void DurableStore::apply_locked(const SchedulerChanges& c, std::vector<std::pair<std::string, int64_t>>& appended) {
  Transaction tx(db_);
  for (const JobRow& r : c.jobs) {
    const JobStatus& s = r.status;
    const JobParams& p = s.params;
    // The job's workers are rows of job_workers; the column keeps the list a database of an older build holds.
    Statement& st = db_.statement(
        "INSERT INTO jobs(id, seq, name, priority, width, height, tile_size, spp, seed, scene_hash, state, created_ms,"
        " started_ms, finished_ms, error, rays, workers, worker_failures, worker_last_error, tile_timeout_s,"
        " frame_total, frame_order, sequence, frame, owner, require, max_workers, pipeline)"
        " VALUES(?,?,?,?,?,?,?,?,?,?,?,?,?,?,?,?,?,?,?,?,?,?,?,?,?,?,?,?)"
        " ON CONFLICT(id) DO UPDATE SET priority = excluded.priority, spp = excluded.spp, state = excluded.state,"
        " started_ms = excluded.started_ms,"
        " finished_ms = excluded.finished_ms, error = excluded.error, rays = excluded.rays,"
        " worker_failures = excluded.worker_failures, worker_last_error = excluded.worker_last_error");
    st.bind_text(1, s.id).bind(2, int64_t(r.seq)).bind_text(3, p.name).bind(4, int64_t(p.priority));
    st.bind(5, int64_t(p.width)).bind(6, int64_t(p.height)).bind(7, int64_t(p.tile_size)).bind(8, int64_t(p.spp));
    st.bind(9, int64_t(p.seed)).bind_text(10, p.scene_hash).bind_text(11, to_string(s.state)).bind(12, s.created_ms);
    st.bind(13, s.started_ms).bind(14, s.finished_ms);
    if (s.error) st.bind_text(15, *s.error);
    st.bind(16, int64_t(s.rays)).bind_text(17, "[]").bind_text(18, json(r.worker_failures).dump());
    st.bind_text(19, map_json(r.worker_last_error).dump()).bind(20, p.tile_timeout_seconds);
    st.bind(21, s.frames ? s.frames->total : 0).bind_text(22, to_string(p.frame_order));
    st.bind_text(23, s.sequence.value_or("")).bind(24, s.frame.value_or(0));
    st.bind_text(25, p.owner).bind_text(26, json(p.require).dump()).bind(27, p.max_workers);
    json pipeline = json::object();
    protocol::put_pipeline(pipeline, p.pipeline);
    st.bind_text(28, pipeline.dump());
    st.run();
  }
  for (const JobWorkerRow& r : c.job_workers)
    db_.statement("INSERT OR REPLACE INTO job_workers(job, idx, worker) VALUES(?,?,?)")
        .bind_text(1, r.job)
        .bind(2, r.index)
        .bind_text(3, r.worker)
        .run();
  for (const TileRow& r : c.tiles) {
    // A tile that became done: its bytes go to the end of its job's pixel file (one write, flushed before the
    // database by the next sync), its row names where they are. A tile that is done no more keeps its reference
    // until a new upload replaces it.
    std::optional<PixelRef> ref;
    if (r.pixels) {
      TESSERA_FAIL_POINT("store.tile_commit");
      const std::string& job = r.job;
      const auto before = std::find_if(appended.begin(), appended.end(), [&](const auto& a) { return a.first == job; });
      const PixelRef written = pixels_.append(job, *r.pixels);
      if (before == appended.end()) appended.emplace_back(job, written.offset);
      ref = written;
    }
    const std::string failures = map_json(r.failures).dump();
    const std::string logs = json(r.logs).dump();
    const std::string log = json(r.log).dump(-1, ' ', false, json::error_handler_t::replace);
    Statement& up = db_.statement(
        ref ? "UPDATE tiles SET state = ?, lease = ?, failures = ?, attempts = ?, render_ms = ?, rays = ?, logs = ?,"
              " rendered_by = ?, log = ?, log_not_kept = ?, pixels = NULL, pixel_offset = ?, pixel_length = ?,"
              " pixel_checksum = ? WHERE job = ? AND idx = ?"
            : "UPDATE tiles SET state = ?, lease = ?, failures = ?, attempts = ?, render_ms = ?, rays = ?, logs = ?,"
              " rendered_by = ?, log = ?, log_not_kept = ? WHERE job = ? AND idx = ?");
    up.bind_text(1, to_string(r.state)).bind_text(2, r.lease).bind_text(3, failures);
    up.bind(4, r.attempts).bind(5, r.render_ms).bind(6, int64_t(r.rays)).bind_text(7, logs);
    up.bind_text(8, r.rendered_by).bind_text(9, log).bind(10, int64_t(r.log_not_kept));
    int next = 11;
    if (ref) {
      up.bind(11, ref->offset).bind(12, ref->length).bind(13, int64_t(ref->checksum));
      next = 14;
    }
    up.bind_text(next, r.job).bind(next + 1, r.index);
    up.run();
    if (db_.changes() > 0) continue;
    Statement& ins = db_.statement(
        "INSERT INTO tiles(job, idx, state, lease, failures, attempts, render_ms, rays, logs, rendered_by, log,"
        " log_not_kept, pixel_offset, pixel_length, pixel_checksum) VALUES(?,?,?,?,?,?,?,?,?,?,?,?,?,?,?)");
    ins.bind_text(1, r.job).bind(2, r.index).bind_text(3, to_string(r.state)).bind_text(4, r.lease).bind_text(5, failures);
    ins.bind(6, r.attempts).bind(7, r.render_ms).bind(8, int64_t(r.rays)).bind_text(9, logs).bind_text(10, r.rendered_by);
    ins.bind_text(11, log).bind(12, int64_t(r.log_not_kept));
    if (ref) ins.bind(13, ref->offset).bind(14, ref->length).bind(15, int64_t(ref->checksum));
    ins.run();
  }
  for (const LeaseRow& r : c.leases) {
    Statement& st = db_.statement(
        "INSERT INTO leases(id, job, tile, worker, deadline_ms, state, granted_ms) VALUES(?,?,?,?,?,?,?)"
        " ON CONFLICT(id) DO UPDATE SET deadline_ms = excluded.deadline_ms, state = excluded.state");
    st.bind_text(1, r.lease.id).bind_text(2, r.lease.job).bind(3, r.lease.tile).bind_text(4, r.lease.worker);
    st.bind(5, r.lease.deadline_ms).bind_text(6, to_string(r.state)).bind(7, r.granted_ms);
    st.run();
  }
  for (const WorkerRow& r : c.workers)
    db_.statement("INSERT OR REPLACE INTO workers(id, name, drained, secret_sha256, tags) VALUES(?,?,?,?,?)")
        .bind_text(1, r.id)
        .bind_text(2, r.name)
        .bind(3, int64_t(r.drained))
        .bind_text(4, r.secret_hash)
        .bind_text(5, json(r.tags).dump())
        .run();
  for (const std::string& id : c.forgotten_workers) db_.statement("DELETE FROM workers WHERE id = ?").bind_text(1, id).run();
  // Only the counters that changed since the last commit. The id sequence is stored a block ahead (the next ids to
  // hand out are always below the stored value, so a restart continues above every id used): a lease grant, which
  // takes an id, then writes no counter.
  CounterRow stored = written_counters_;
  if (c.counters.next_seq > written_counters_.next_seq) stored.next_seq = c.counters.next_seq + kIdBlock;
  stored.tiles_rendered = c.counters.tiles_rendered;
  stored.lease_expiries = c.counters.lease_expiries;
  stored.rays = c.counters.rays;
  const std::tuple<const char*, uint64_t, uint64_t> counters[] = {
      {"next_seq", stored.next_seq, written_counters_.next_seq},
      {"tiles_rendered", stored.tiles_rendered, written_counters_.tiles_rendered},
      {"lease_expiries", stored.lease_expiries, written_counters_.lease_expiries},
      {"rays", stored.rays, written_counters_.rays}};
  // An upsert changes the row in place (the table's page only), where a replacement would delete and insert it and
  // so rewrite its key's index page too: one page fewer in the log for every tile.
  for (const auto& [key, value, written] : counters)
    if (value != written)
      db_.statement("INSERT INTO meta(key, value) VALUES(?,?) ON CONFLICT(key) DO UPDATE SET value = excluded.value")
          .bind_text(1, key)
          .bind(2, int64_t(value))
          .run();
  for (const OutboxRow& r : c.outbox)
    db_.statement("INSERT OR IGNORE INTO webhook_outbox(id, url, event, job, created_ms, body, next_ms) VALUES(?,?,?,?,?,?,?)")
        .bind_text(1, r.id)
        .bind_text(2, r.url)
        .bind_text(3, r.event)
        .bind_text(4, r.job)
        .bind(5, r.created_ms)
        .bind_text(6, r.body)
        .bind(7, r.created_ms)
        .run();
  for (const std::string& job : c.purged_jobs)
    for (const char* sql : {"DELETE FROM leases WHERE job = ?", "DELETE FROM tile_states WHERE job = ?",
                            "DELETE FROM tiles WHERE job = ?", "DELETE FROM job_records WHERE id = ?",
                            "DELETE FROM job_workers WHERE job = ?", "DELETE FROM jobs WHERE id = ?"})
      db_.statement(sql).bind_text(1, job).run();
  tx.commit();
  appended.clear();  // stored: nothing to cut back from here on
  written_counters_ = stored;
  // A purged job's pixel file goes once no durable row can name it any more: after the next flush of the database,
  // asked for here (without flushes, now).
  for (const std::string& job : c.purged_jobs) {
    if (durability_ == Durability::machine) {
      pixels_.remove_when_flushed(job);
      group_.after_flush([] {});
    } else {
      try {
        pixels_.remove(job);
      } catch (const StorageError& e) {
        spdlog::warn("{} (removed when the coordinator next starts)", e.what());
      }
    }
  }
  if (!c.purged_jobs.empty()) give_back_free_pages();
}

void DurableStore::give_back_free_pages() {
  // The freed pages leave the file (auto_vacuum=INCREMENTAL), and the write-ahead log that carried the deletion is
  // copied into it and cut to zero bytes. The checkpointer's connection does that, after any checkpoint of its own
  // in progress: a checkpoint from this connection would find its checkpoint lock taken and give up at once
  // (SQLITE_BUSY, reported only in the pragma's result row), leaving the log at its size.
  db_.exec("PRAGMA incremental_vacuum");
  checkpointer_->truncate();
}

SchedulerSnapshot DurableStore::load() {
  std::lock_guard lock(mu_);
  SchedulerSnapshot snap;
  Transaction tx(db_);  // one consistent view
  {
    Statement& st = db_.statement("SELECT key, value FROM meta");
    while (st.step()) {
      const std::string key = st.text(0);
      const uint64_t v = uint64_t(st.integer(1));
      if (key == "next_seq") snap.counters.next_seq = v;
      else if (key == "tiles_rendered") snap.counters.tiles_rendered = v;
      else if (key == "lease_expiries") snap.counters.lease_expiries = v;
      else if (key == "rays") snap.counters.rays = v;
    }
    written_counters_ = snap.counters;
  }
  {
    Statement& st = db_.statement(
        "SELECT id, seq, name, priority, width, height, tile_size, spp, seed, scene_hash, state, created_ms, started_ms,"
        " finished_ms, error, rays, workers, worker_failures, worker_last_error, tile_timeout_s, frame_total,"
        " frame_order, sequence, frame, owner, require, max_workers, pipeline FROM jobs ORDER BY seq");
    while (st.step()) {
      JobRow r;
      JobStatus& s = r.status;
      s.id = st.text(0);
      r.seq = uint64_t(st.integer(1));
      s.params.name = st.text(2);
      s.params.priority = int(st.integer(3));
      s.params.width = int(st.integer(4));
      s.params.height = int(st.integer(5));
      s.params.tile_size = int(st.integer(6));
      s.params.spp = uint32_t(st.integer(7));
      s.params.seed = uint64_t(st.integer(8));
      s.params.scene_hash = st.text(9);
      try {
        s.state = job_state_from_string(st.text(10));
      } catch (const std::invalid_argument& e) {
        throw StorageError("job " + s.id + ": " + e.what());
      }
      s.created_ms = st.integer(11);
      if (!st.is_null(12)) s.started_ms = st.integer(12);
      if (!st.is_null(13)) s.finished_ms = st.integer(13);
      if (!st.is_null(14)) s.error = st.text(14);
      s.rays = uint64_t(st.integer(15));
      s.workers = json_list(st.text(16), "job " + s.id + ": stored workers");
      r.worker_failures = json_map<int>(st.text(17), "worker failures");
      r.worker_last_error = json_map<std::string>(st.text(18), "worker errors");
      s.params.tile_timeout_seconds = st.integer(19);
      if (st.integer(20) > 0) s.frames = protocol::FrameCounts{.total = st.integer(20)};
      try {
        s.params.frame_order = protocol::frame_order_from_string(st.text(21));
      } catch (const std::invalid_argument& e) {
        throw StorageError("job " + s.id + ": " + e.what());
      }
      if (!st.text(22).empty()) {
        s.sequence = st.text(22);
        s.frame = st.integer(23);
      }
      s.params.owner = st.text(24);
      s.params.require = json_list(st.text(25), "job " + s.id + ": stored requirements");
      s.params.max_workers = st.integer(26);
      try {
        s.params.pipeline = protocol::answer_pipeline(json::parse(st.text(27)));
      } catch (const std::exception& e) {
        throw StorageError("job " + s.id + ": stored pipeline is unreadable: " + e.what());
      }
      snap.jobs.push_back(std::move(r));
    }
  }
  {
    // Each job's workers after those its row's column lists (an older build wrote the whole list there).
    std::map<std::string, JobRow*> by_id;
    for (JobRow& r : snap.jobs) by_id[r.status.id] = &r;
    Statement& st = db_.statement("SELECT job, worker FROM job_workers ORDER BY job, idx");
    while (st.step()) {
      const auto it = by_id.find(st.text(0));
      if (it == by_id.end()) continue;
      it->second->status.workers.push_back(st.text(1));
    }
  }
  std::vector<TileRow*> damaged;  // done tiles whose bytes are not in their pixel file intact
  {
    std::set<std::string> jobs;
    for (const JobRow& r : snap.jobs) jobs.insert(r.status.id);
    if (const size_t n = pixels_.keep_only(jobs)) spdlog::info("removed the pixel files of {} deleted job(s)", n);
  }
  {
    Statement& st = db_.statement(
        "SELECT job, idx, state, lease, failures, attempts, render_ms, rays, logs, rendered_by, log, log_not_kept,"
        " pixel_offset, pixel_length, pixel_checksum FROM tiles");
    std::vector<std::pair<size_t, PixelRef>> refs;  // done tiles' references, checked below
    // Only the tiles whose bytes will be read: those of jobs not done, and of done jobs without their result file
    // (the machine stopped before it was written). A done job's result holds its pixels; reading every done tile of
    // a long history at each start would cost as much as the history.
    std::set<std::string> checked;
    for (const JobRow& r : snap.jobs)
      if (r.status.state != JobState::done || !fs::exists(result_path(r.status.id))) checked.insert(r.status.id);
    while (st.step()) {
      TileRow r;
      r.job = st.text(0);
      r.index = st.integer(1);
      try {
        r.state = tile_state_from_string(st.text(2));
      } catch (const std::invalid_argument& e) {
        throw StorageError(tile_name(r.job, r.index) + ": " + e.what());
      }
      r.lease = st.text(3);
      r.failures = json_map<std::string>(st.text(4), "tile failures");
      r.attempts = st.integer(5);
      r.render_ms = st.integer(6);
      r.rays = uint64_t(st.integer(7));
      r.logs = json_map<std::vector<std::string>>(st.text(8), "tile failure logs");
      r.rendered_by = st.text(9);
      r.log = json_list(st.text(10), tile_name(r.job, r.index) + ": stored log");
      r.log_not_kept = st.integer(11) != 0;
      if (r.state == TileState::done && !st.is_null(13) && checked.count(r.job))
        refs.emplace_back(snap.tiles.size(), PixelRef{st.integer(12), st.integer(13), uint64_t(st.integer(14))});
      snap.tiles.push_back(std::move(r));
    }
    // Each file read front to back.
    std::sort(refs.begin(), refs.end(), [&](const auto& a, const auto& b) {
      return std::tie(snap.tiles[a.first].job, a.second.offset) < std::tie(snap.tiles[b.first].job, b.second.offset);
    });
    for (const auto& [i, ref] : refs)
      if (!pixels_.read(snap.tiles[i].job, ref)) damaged.push_back(&snap.tiles[i]);
  }
  for (TileRow* t : damaged) {
    // Its row reached the disk and its bytes did not: the machine stopped before the flush that would have
    // acknowledged it. It is rendered again.
    spdlog::warn("{}: its pixels are not in {} intact (the machine stopped before they were flushed); the tile is "
                 "pending again", tile_name(t->job, t->index), pixels_.file_of(t->job).string());
    t->state = TileState::pending;
    t->lease.clear();
    db_.statement("UPDATE tiles SET state = ?, lease = '', pixel_offset = NULL, pixel_length = NULL,"
                  " pixel_checksum = NULL WHERE job = ? AND idx = ?")
        .bind_text(1, to_string(TileState::pending))
        .bind_text(2, t->job)
        .bind(3, t->index)
        .run();
    for (JobRow& j : snap.jobs) {
      if (j.status.id != t->job || j.status.state != JobState::done) continue;
      spdlog::warn("job {}: running again to render its tile {}", j.status.id, t->index);
      j.status.state = JobState::running;
      j.status.finished_ms.reset();
      db_.statement("UPDATE jobs SET state = ?, finished_ms = NULL WHERE id = ?")
          .bind_text(1, to_string(JobState::running))
          .bind_text(2, j.status.id)
          .run();
    }
  }
  {
    Statement& st = db_.statement("SELECT id, job, tile, worker, deadline_ms, state, granted_ms FROM leases");
    while (st.step()) {
      LeaseRow r;
      r.lease.id = st.text(0);
      r.lease.job = st.text(1);
      r.lease.tile = st.integer(2);
      r.lease.worker = st.text(3);
      r.lease.deadline_ms = st.integer(4);
      try {
        r.state = lease_state_from_string(st.text(5));
      } catch (const std::invalid_argument& e) {
        throw StorageError("lease " + r.lease.id + ": " + e.what());
      }
      r.granted_ms = st.integer(6);
      snap.leases.push_back(std::move(r));
    }
  }
  {
    Statement& st = db_.statement("SELECT id, name, drained, secret_sha256, tags FROM workers");
    while (st.step()) {
      WorkerRow w{st.text(0), st.text(1), st.integer(2) != 0, st.text(3)};
      w.tags = json_list(st.text(4), "worker " + w.id + ": stored tags");
      snap.workers.push_back(std::move(w));
    }
  }
  tx.commit();
  return snap;
}

void DurableStore::save_record(const std::string& job, const json& record) {
  std::lock_guard lock(mu_);
  write_locked([&] {
    db_.statement("INSERT OR REPLACE INTO job_records(id, record) VALUES(?,?)").bind_text(1, job).bind_text(2, record.dump()).run();
  });
}

void DurableStore::save_record_texts(const std::vector<std::pair<std::string, std::string>>& records) {
  std::lock_guard lock(mu_);
  write_locked([&] {
    Transaction tx(db_);
    for (const auto& [job, text] : records)
      db_.statement("INSERT OR REPLACE INTO job_records(id, record) VALUES(?,?)").bind_text(1, job).bind_text(2, text).run();
    tx.commit();
  });
}

std::optional<json> DurableStore::load_record(const std::string& job) {
  std::string text;
  {
    std::lock_guard lock(mu_);
    Statement& st = db_.statement("SELECT record FROM job_records WHERE id = ?");
    st.bind_text(1, job);
    if (!st.step()) return std::nullopt;
    text = st.text(0);
    st.reset();
  }
  try {
    return json::parse(text);
  } catch (const json::exception& e) {
    throw StorageError("job " + job + ": stored record is not JSON: " + e.what());
  }
}

std::vector<std::pair<int64_t, std::string>> DurableStore::tile_pixels(const std::string& job) {
  std::vector<std::pair<int64_t, std::string>> out;
  std::vector<std::pair<size_t, PixelRef>> refs;  // tiles of `out` whose bytes are in the pixel file
  {
    std::lock_guard lock(mu_);
    Statement& st = db_.statement(
        "SELECT idx, pixels, pixel_offset, pixel_length, pixel_checksum FROM tiles WHERE job = ? AND state = 'done'"
        " ORDER BY idx");
    st.bind_text(1, job);
    while (st.step()) {
      if (!st.is_null(3)) refs.emplace_back(out.size(), PixelRef{st.integer(2), st.integer(3), uint64_t(st.integer(4))});
      out.emplace_back(st.integer(0), st.is_null(3) ? st.blob(1) : std::string());  // version 1 kept the bytes here
    }
  }
  // Read without the store's lock (appends go on meanwhile; a done tile's bytes never change).
  for (const auto& [i, ref] : refs) {
    auto bytes = pixels_.read(job, ref);
    if (!bytes)
      throw StorageError(tile_name(job, out[i].first) + ": its pixels are not in " + pixels_.file_of(job).string() +
                         " intact");
    out[i].second = std::move(*bytes);
  }
  return out;
}

void DurableStore::save_tile_state(const std::string& job, int64_t tile, uint32_t spp, std::string_view exr) {
  std::lock_guard lock(mu_);
  write_locked([&] {
    db_.statement("INSERT OR REPLACE INTO tile_states(job, idx, spp, exr) VALUES(?,?,?,?)")
        .bind_text(1, job)
        .bind(2, tile)
        .bind(3, int64_t(spp))
        .bind_blob(4, exr)
        .run();
  });
}

std::optional<uint32_t> DurableStore::tile_state_spp(const std::string& job, int64_t tile) {
  std::lock_guard lock(mu_);
  Statement& st = db_.statement("SELECT spp FROM tile_states WHERE job = ? AND idx = ?");
  st.bind_text(1, job).bind(2, tile);
  if (!st.step()) return std::nullopt;
  const auto spp = uint32_t(st.integer(0));
  st.reset();
  return spp;
}

std::optional<std::pair<uint32_t, std::string>> DurableStore::tile_state(const std::string& job, int64_t tile) {
  std::lock_guard lock(mu_);
  Statement& st = db_.statement("SELECT spp, exr FROM tile_states WHERE job = ? AND idx = ?");
  st.bind_text(1, job).bind(2, tile);
  if (!st.step()) return std::nullopt;
  std::pair<uint32_t, std::string> out{uint32_t(st.integer(0)), st.blob(1)};
  st.reset();
  return out;
}

std::vector<DueDelivery> DurableStore::due_deliveries(int64_t now, size_t limit, const std::set<std::string>& skip) {
  std::lock_guard lock(mu_);
  // Address by address over the (state, url, next_ms) index: each address with pending rows is found by one seek
  // past the one before, and only the first `limit` due rows of an address not skipped are read. One query over
  // every pending row filtered by address read all the rows of a skipped one (a receiver down for long holds many):
  // 34 ms at 100,000 of them, under the store's lock.
  struct Row {
    int64_t next_ms, rowid;
    DueDelivery d;
  };
  std::vector<Row> rows;
  std::string url;
  for (;;) {
    Statement& next = db_.statement(
        "SELECT url FROM webhook_outbox WHERE state = 'pending' AND url > ? ORDER BY url LIMIT 1");
    next.bind_text(1, url);
    if (!next.step()) break;
    url = next.text(0);
    next.reset();
    if (skip.count(url)) continue;
    Statement& st = db_.statement(
        "SELECT id, body, attempts, next_ms, rowid FROM webhook_outbox WHERE state = 'pending' AND url = ?"
        " AND next_ms <= ? ORDER BY next_ms, rowid LIMIT ?");
    st.bind_text(1, url).bind(2, now).bind(3, int64_t(limit));
    while (st.step()) rows.push_back({st.integer(3), st.integer(4), {st.text(0), url, st.text(1), st.integer(2)}});
  }
  // The earliest due first, as one query ordered by next_ms would give them.
  std::sort(rows.begin(), rows.end(),
            [](const Row& a, const Row& b) { return std::tie(a.next_ms, a.rowid) < std::tie(b.next_ms, b.rowid); });
  std::vector<DueDelivery> out;
  for (size_t k = 0; k < rows.size() && k < limit; ++k) out.push_back(std::move(rows[k].d));
  return out;
}

void DurableStore::record_attempt(const std::string& id, const std::string& url, const DeliveryAttempt& a) {
  std::lock_guard lock(mu_);
  write_locked([&] {
    Statement& st = db_.statement(
        "UPDATE webhook_outbox SET state = ?, attempts = attempts + 1, next_ms = ?, last_status = ?, last_error = ?"
        " WHERE id = ? AND url = ?");
    st.bind_text(1, a.state).bind(2, a.next_ms.value_or(0));
    if (a.status) st.bind(3, int64_t(*a.status));
    if (a.error) st.bind_text(4, *a.error);
    st.bind_text(5, id).bind_text(6, url);
    st.run();
  });
}

std::vector<protocol::WebhookDelivery> DurableStore::deliveries(size_t limit) {
  std::lock_guard lock(mu_);
  std::vector<protocol::WebhookDelivery> out;
  Statement& st = db_.statement(
      "SELECT id, url, event, job, state, attempts, created_ms, next_ms, last_status, last_error FROM webhook_outbox"
      " ORDER BY rowid DESC LIMIT ?");
  st.bind(1, int64_t(limit));
  while (st.step()) {
    protocol::WebhookDelivery d{st.text(0), st.text(1), st.text(2), st.text(3), st.text(4), st.integer(5), st.integer(6),
                                std::nullopt, std::nullopt, std::nullopt};
    if (d.state == "pending") d.next_ms = st.integer(7);
    if (!st.is_null(8)) d.last_status = int(st.integer(8));
    if (!st.is_null(9)) d.last_error = st.text(9);
    out.push_back(std::move(d));
  }
  return out;
}

void DurableStore::append_audit(const protocol::AuditEntry& e) {
  std::lock_guard lock(mu_);
  write_locked([&] {
    db_.statement("INSERT INTO audit(at_ms, user, role, action, target, address, status) VALUES(?,?,?,?,?,?,?)")
        .bind(1, e.at_ms)
        .bind_text(2, e.user)
        .bind_text(3, e.role)
        .bind_text(4, e.action)
        .bind_text(5, e.target)
        .bind_text(6, e.address)
        .bind(7, int64_t(e.status))
        .run();
  });
}

protocol::AuditList DurableStore::audit(const protocol::AuditQuery& q) {
  std::lock_guard lock(mu_);
  Statement& st = db_.statement(
      "SELECT id, at_ms, user, role, action, target, address, status FROM audit"
      " WHERE id < ? AND (? = '' OR user = ?) ORDER BY id DESC LIMIT ?");
  st.bind(1, q.before.value_or(std::numeric_limits<int64_t>::max())).bind_text(2, q.user).bind_text(3, q.user);
  st.bind(4, int64_t(q.limit) + 1);
  protocol::AuditList out;
  while (st.step()) {
    if (out.entries.size() == q.limit) {
      out.next = out.entries.back().id;
      st.reset();
      break;
    }
    out.entries.push_back({st.integer(0), st.integer(1), st.text(2), st.text(3), st.text(4), st.text(5), st.text(6),
                           int(st.integer(7))});
  }
  return out;
}

int64_t DurableStore::forget_audit(int64_t before_ms) {
  std::lock_guard lock(mu_);
  int64_t n = 0;
  write_locked([&] {
    db_.statement("DELETE FROM audit WHERE at_ms < ?").bind(1, before_ms).run();
    n = db_.changes();
  });
  return n;
}

}  // namespace tessera::server
