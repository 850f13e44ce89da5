// Checking, before the work that produces it, that an output file can be written.
#pragma once

#include <filesystem>
#include <string>

namespace tessera {

/// Throws std::runtime_error (naming the file and the reason) unless a file can be created at `path`: its folder
/// exists and accepts new files, and `path` is not a folder. Probes by creating and removing a uniquely named file
/// beside it, so an existing file at `path` is left untouched and nothing stays behind.
void check_output_writable(const std::filesystem::path& path, const std::string& what = "output");

}  // namespace tessera
