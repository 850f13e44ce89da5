#include "server/auth.h"

#include "core/sha256.h"

#include <openssl/crypto.h>
#include <openssl/rand.h>

#include <stdexcept>

namespace tessera::server {

bool constant_time_equal(std::string_view a, std::string_view b) {
  // Hashing first makes the comparison independent of the lengths; CRYPTO_memcmp does not stop at the first difference.
  const std::string ha = sha256_hex(a), hb = sha256_hex(b);
  return CRYPTO_memcmp(ha.data(), hb.data(), ha.size()) == 0;
}

std::string generate_token() {
  unsigned char bytes[24];
  if (RAND_bytes(bytes, sizeof bytes) != 1) throw std::runtime_error("the system random source failed; cannot make a token");
  static const char* digits = "0123456789abcdef";
  std::string out;
  for (unsigned char b : bytes) {
    out += digits[b >> 4];
    out += digits[b & 15];
  }
  return out;
}

std::string token_problem(std::string_view token) {
  if (token.size() < 16) return "a token must have at least 16 characters (it has " + std::to_string(token.size()) + ")";
  if (token.size() > 4096) return "a token must have at most 4096 characters";
  for (char c : token)
    if (c <= ' ' || c > '~') return "a token may contain only printable ASCII characters without spaces";
  return "";
}

namespace {

const char* role_name(Access a) {
  switch (a) {
    case Access::client: return "the client token";
    case Access::worker: return "the worker token";
    case Access::either: return "the client or the worker token";
    case Access::open: break;
  }
  return "no token";
}

}  // namespace

AuthDecision authorize(Access need, std::string_view authorization, const AccessTokens& tokens) {
  if (need == Access::open) return {};
  const bool need_client = need == Access::client || need == Access::either;
  const bool need_worker = need == Access::worker || need == Access::either;
  // An endpoint whose token is not configured is open (the coordinator then listens on loopback only).
  const bool open = need == Access::client   ? tokens.client.empty()
                    : need == Access::worker ? tokens.worker.empty()
                                             : tokens.client.empty() && tokens.worker.empty();
  if (open) return {};
  constexpr std::string_view kScheme = "Bearer ";
  if (authorization.empty()) return {AuthDecision::missing, std::string("this endpoint needs ") + role_name(need) + " (Authorization: Bearer <token>)"};
  if (authorization.size() <= kScheme.size() || authorization.substr(0, kScheme.size()) != kScheme)
    return {AuthDecision::invalid, "the Authorization header must be 'Bearer <token>'"};
  const std::string_view presented = authorization.substr(kScheme.size());
  // Both comparisons always run, so the time taken does not say which token (if any) matched.
  const bool is_client = !tokens.client.empty() && constant_time_equal(presented, tokens.client);
  const bool is_worker = !tokens.worker.empty() && constant_time_equal(presented, tokens.worker);
  if ((need_client && is_client) || (need_worker && is_worker)) return {};
  if (is_client || is_worker)
    return {AuthDecision::wrong_role, std::string("this endpoint needs ") + role_name(need) + "; the " +
                                          (is_client ? "client" : "worker") + " token was given"};
  return {AuthDecision::invalid, "the bearer token is not valid for this coordinator"};
}

}  // namespace tessera::server
