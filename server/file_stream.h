// A file sent as a response body in bounded pieces: the connection holds one piece at a time, and reads the next only
// when the previous one is written, so a client that reads slowly (or not at all) costs one piece, not the file.
#pragma once

#include "server/http_server.h"

#include <cstdint>
#include <filesystem>
#include <memory>

namespace tessera::server {

/// Bytes read from the file per piece.
inline constexpr std::size_t kFilePieceBytes = 256 * 1024;

/// A 200 answer whose body is the file at `path`, read piece by piece as the connection writes (Content-Length set).
/// The file is opened now, so removing it later does not cut the answer short; returns nothing when it cannot be
/// opened (the caller answers 404), throws std::runtime_error when it is not a regular file.
std::optional<HttpReply> file_reply(const std::filesystem::path& path, const char* content_type, unsigned version);

}  // namespace tessera::server
