// SHA-256 digests (OpenSSL's EVP interface) for content addressing and scene hashes.
#pragma once

#include <array>
#include <cstdint>
#include <filesystem>
#include <memory>
#include <span>
#include <string>
#include <string_view>

namespace tessera {

/// An incremental SHA-256 hasher.
class Sha256 {
 public:
  Sha256();
  ~Sha256();
  Sha256(const Sha256&) = delete;
  Sha256& operator=(const Sha256&) = delete;
  /// Feeds bytes.
  void update(std::span<const uint8_t> bytes);
  /// Feeds a string's bytes.
  void update(std::string_view s) { update({reinterpret_cast<const uint8_t*>(s.data()), s.size()}); }
  /// The digest as 64 lowercase hex characters; the hasher is finished afterwards.
  std::string hex();

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

/// A SHA-256 digest's 32 bytes.
using Sha256Digest = std::array<uint8_t, 32>;

/// SHA-256 of a byte string.
Sha256Digest sha256_digest(std::string_view bytes);

/// SHA-256 of a byte string, as lowercase hex.
std::string sha256_hex(std::string_view bytes);

/// SHA-256 of a file's contents, as lowercase hex; throws std::runtime_error naming the file on I/O errors.
std::string sha256_file(const std::filesystem::path& path);

/// True when s is 64 lowercase hex characters.
bool is_sha256_hex(std::string_view s);

/// For a process that uses OpenSSL for these digests only (a render on this machine): starts OpenSSL without reading
/// the system's configuration file (openssl.cnf), without its legacy tables of cipher and digest names and without
/// its clean-up at exit, which together cost more instructions than hashing a scene; the digests are the same. Call it
/// before any other use of OpenSSL in the process, and never in a process that also speaks TLS, whose protocols and
/// ciphers that file may set. Throws std::runtime_error when OpenSSL cannot start.
void start_openssl_for_digests_only();

}  // namespace tessera
