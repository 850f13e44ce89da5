#include "server/worker_secret.h"

#include "core/util/sha256.h"
#include "server/auth.h"

#include <openssl/crypto.h>

namespace tessera::server {

std::string new_worker_secret() { return generate_token(); }

std::string worker_secret_hash(std::string_view secret) { return sha256_hex(secret); }

bool worker_secret_matches(std::string_view stored_hash, std::string_view presented) {
  if (stored_hash.empty()) return false;
  const std::string hash = worker_secret_hash(presented);  // always 64 digits, whatever was presented
  return stored_hash.size() == hash.size() && CRYPTO_memcmp(stored_hash.data(), hash.data(), hash.size()) == 0;
}

}  // namespace tessera::server
