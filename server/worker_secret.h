// A worker's secret: made at its registration, presented by the worker with every request that acts as it, and kept
// by the coordinator only as its SHA-256 (stored with the worker, so it outlives a restart).
#pragma once

#include <string>
#include <string_view>

namespace tessera::server {

/// A fresh secret from the operating system's cryptographic random source (192 bits, 48 lowercase hex digits).
std::string new_worker_secret();

/// What the coordinator keeps of a secret: its SHA-256, 64 lowercase hex digits.
std::string worker_secret_hash(std::string_view secret);

/// True when `presented` is the secret whose hash is `stored_hash`, compared in time independent of where they
/// differ; an empty stored hash matches no secret.
bool worker_secret_matches(std::string_view stored_hash, std::string_view presented);

}  // namespace tessera::server
