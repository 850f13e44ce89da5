// Whole files: read one, or replace one atomically and durably (the coordinator's results and blobs, a client's
// downloaded result).
#pragma once

#include <filesystem>
#include <stdexcept>
#include <string>
#include <string_view>

namespace tessera {

/// A file operation that failed for a reason other than the caller's input (missing file, disk full, permissions).
struct FileError : std::runtime_error {
  using std::runtime_error::runtime_error;
};

/// Writes bytes to `path` atomically: a uniquely named temp file beside it, fsync, rename, fsync of the folder, so
/// readers see the old file or the whole new one, also after a crash. Throws FileError naming the file and the cause.
void write_file_atomic(const std::filesystem::path& path, std::string_view bytes);

/// Makes a rename or creation of `file` durable by syncing the folder that holds it (the working directory for a bare
/// name). Best effort: some file systems refuse folder handles, and the file is in place either way.
void sync_folder_of(const std::filesystem::path& file);

/// Reads a whole file; throws FileError naming it.
std::string read_file_bytes(const std::filesystem::path& path);

/// A fresh unique name (for temp files), e.g. "3f9a1c0d2b4e5f60".
std::string random_hex(int bytes);

}  // namespace tessera
