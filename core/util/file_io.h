// Whole files: read one, or replace one atomically, flushed to the disk or not (the coordinator's results and blobs,
// a client's downloaded result, the renderer's images, a worker's cached assets).
#pragma once

#include <cstdint>
#include <filesystem>
#include <functional>
#include <span>
#include <stdexcept>
#include <string>
#include <string_view>

namespace tessera {

/// A file operation that failed for a reason other than the caller's input (missing file, disk full, permissions).
struct FileError : std::runtime_error {
  using std::runtime_error::runtime_error;
  /// `what`, caused by the system error `error` (an errno value).
  FileError(const std::string& what, int error) : std::runtime_error(what), error(error) {}
  int error = 0;  ///< The errno of the call that failed (ENOSPC: the disk is full), 0 when none is known.
};

/// How much of a crash a replaced file survives: the machine's (the file and its folder flushed to the disk before the
/// write returns) or only the process's (the page cache keeps every write; for files that die with their process).
enum class Flush { to_disk, none };

/// Writes all of `bytes` to descriptor `fd`, again after a short write or EINTR; 0, or the errno of the write that
/// failed (EIO for one that wrote nothing).
int write_all(int fd, std::string_view bytes);

/// The size of flush_to_disk's steps (bench/flush_steps.cpp measures it).
inline constexpr int64_t kFlushStep = int64_t(1) << 20;

/// Flushes the file open at `fd` to the disk (fsync), its data written out first in steps of kFlushStep bytes, each
/// finished before the next begins: a large file then never queues megabytes at the disk ahead of another file's
/// small flush (the coordinator's log, whose flush acknowledges uploads, waits behind one step at most). 0, or the
/// errno of the fsync that failed.
int flush_to_disk(int fd);

/// Replaces `path` with `bytes` atomically: a temp file beside it (temp_path_beside), written, flushed as `flush`
/// says (flush_to_disk), renamed over `path`; readers see the old file or the whole new one. On failure the temp file
/// is removed and `path` is left as it was. Throws FileError naming the file and the cause.
void write_file_atomic(const std::filesystem::path& path, std::string_view bytes, Flush flush = Flush::to_disk);
/// The same for bytes held as unsigned (an encoded image).
inline void write_file_atomic(const std::filesystem::path& path, std::span<const uint8_t> bytes,
                              Flush flush = Flush::to_disk) {
  write_file_atomic(path, std::string_view(reinterpret_cast<const char*>(bytes.data()), bytes.size()), flush);
}
/// The same for a file that `write` makes at the temp path it is given (and closes): then flushed, renamed over `path`.
/// On failure, `write`'s included, the temp file is removed and the exception goes on.
void write_file_atomic(const std::filesystem::path& path, const std::function<void(const std::filesystem::path&)>& write,
                       Flush flush = Flush::to_disk);

/// Moves the finished file `from` over `to` atomically and durably: flushed to the disk, renamed, the rename synced;
/// across file systems (EXDEV) it is copied with write_file_atomic instead and stays in place. Throws FileError naming
/// the files and the cause.
void move_file_atomic(const std::filesystem::path& from, const std::filesystem::path& to);

/// A fresh name for the temp file of an atomic replacement of `path`, in its folder: "PATH.<12 hex digits>.tmp", so
/// that writers of one path never share a temp file and a crash's leftovers are found by their ".tmp".
std::filesystem::path temp_path_beside(const std::filesystem::path& path);

/// Makes a rename or creation of `file` durable by syncing the folder that holds it (the working directory for a bare
/// name). Best effort: some file systems refuse folder handles, and the file is in place either way.
void sync_folder_of(const std::filesystem::path& file);

/// Makes the creations, renames and removals of entries in `folder` durable (fsync of the folder). Best effort, as
/// sync_folder_of.
void sync_folder(const std::filesystem::path& folder);

/// Reads a whole file; throws FileError naming it.
std::string read_file_bytes(const std::filesystem::path& path);

/// A fresh unique name (for temp files), e.g. "3f9a1c0d2b4e5f60".
std::string random_hex(int bytes);

}  // namespace tessera
