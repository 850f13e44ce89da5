#include "server/auth.h"

#include "core/util/sha256.h"

#include <openssl/crypto.h>
#include <openssl/rand.h>

#include <algorithm>
#include <cctype>
#include <stdexcept>

namespace tessera::server {

namespace {

// Digests compared in time independent of where they differ.
bool same_digest(const Sha256Digest& a, const Sha256Digest& b) { return CRYPTO_memcmp(a.data(), b.data(), a.size()) == 0; }

}  // namespace

bool constant_time_equal(std::string_view a, std::string_view b) {
  // Hashing first makes the comparison independent of the lengths; CRYPTO_memcmp does not stop at the first difference.
  return same_digest(sha256_digest(a), sha256_digest(b));
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

TokenCheck::TokenCheck(const AccessTokens& tokens) {
  if (!tokens.client.empty()) client_ = sha256_digest(tokens.client);
  if (!tokens.worker.empty()) worker_ = sha256_digest(tokens.worker);
}

AuthDecision TokenCheck::authorize(Access need, std::string_view authorization) const {
  if (need == Access::open) return {};
  const bool need_client = need == Access::client || need == Access::either;
  const bool need_worker = need == Access::worker || need == Access::either;
  // An endpoint whose token is not configured is open (the coordinator then listens on loopback only).
  const bool open = need == Access::client   ? !client_
                    : need == Access::worker ? !worker_
                                             : !client_ && !worker_;
  if (open) return {};
  if (authorization.empty()) return {AuthDecision::missing, std::string("this endpoint needs ") + role_name(need) + " (Authorization: Bearer <token>)"};
  // The scheme is case-insensitive and followed by one or more spaces (RFC 9110, 11.4).
  constexpr std::string_view kScheme = "bearer";
  const bool scheme_ok = authorization.size() > kScheme.size() + 1 && authorization[kScheme.size()] == ' ' &&
                         std::equal(kScheme.begin(), kScheme.end(), authorization.begin(), [](char a, char b) {
                           return a == char(std::tolower(static_cast<unsigned char>(b)));
                         });
  const size_t token_at = scheme_ok ? authorization.find_first_not_of(' ', kScheme.size()) : std::string_view::npos;
  if (token_at == std::string_view::npos)
    return {AuthDecision::invalid, "the Authorization header must be 'Bearer <token>'"};
  const std::string_view presented = authorization.substr(token_at);
  // Both comparisons always run, so the time taken does not say which token (if any) matched.
  const Sha256Digest d = sha256_digest(presented);
  const bool is_client = client_ && same_digest(d, *client_);
  const bool is_worker = worker_ && same_digest(d, *worker_);
  if ((need_client && is_client) || (need_worker && is_worker)) return {};
  if (is_client || is_worker)
    return {AuthDecision::wrong_role, std::string("this endpoint needs ") + role_name(need) + "; the " +
                                          (is_client ? "client" : "worker") + " token was given"};
  return {AuthDecision::invalid, "the bearer token is not valid for this coordinator"};
}

AuthDecision authorize(Access need, std::string_view authorization, const AccessTokens& tokens) {
  return TokenCheck(tokens).authorize(need, authorization);
}

}  // namespace tessera::server
