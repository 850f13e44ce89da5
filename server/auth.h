// Bearer-token access control: which token each endpoint needs and a constant-time check of the Authorization header.
#pragma once

#include "core/util/sha256.h"
#include "protocol/routes.h"

#include <optional>
#include <string>
#include <string_view>

namespace tessera::server {

/// The token a request must carry (each route's, protocol/routes.h).
using Access = protocol::Access;

/// The configured tokens; an empty one leaves its endpoints open (allowed on loopback only).
struct AccessTokens {
  std::string client;  ///< Token clients present.
  std::string worker;  ///< Token workers present.

  /// True when both tokens are set, which is what listening beyond loopback requires.
  bool complete() const { return !client.empty() && !worker.empty(); }
};

/// Outcome of checking a request's credentials.
struct AuthDecision {
  enum Status { allowed, missing, invalid, wrong_role } status = allowed;  ///< Missing/invalid: 401; wrong_role: 403.
  std::string reason;  ///< Text for the error body; never contains a token.
};

/// The configured tokens kept as their digests, so that checking a request hashes only the token it presents.
class TokenCheck {
 public:
  /// Digests of `tokens` (an empty token stays unset: its endpoints are open).
  explicit TokenCheck(const AccessTokens& tokens);
  /// Checks an Authorization header value ("Bearer <token>", possibly empty) against the tokens `need` accepts; every
  /// comparison takes the same time whatever the tokens' contents and lengths.
  AuthDecision authorize(Access need, std::string_view authorization) const;

 private:
  std::optional<Sha256Digest> client_, worker_;
};

/// TokenCheck(tokens).authorize(need, authorization).
AuthDecision authorize(Access need, std::string_view authorization, const AccessTokens& tokens);

/// Equality of two secrets in time independent of where they differ and of their lengths (compares SHA-256 digests).
bool constant_time_equal(std::string_view a, std::string_view b);

/// A fresh token from the operating system's cryptographic random source: 48 lowercase hex digits (192 bits).
std::string generate_token();

/// Checks that a token is usable (16 to 4096 printable ASCII characters without spaces); returns the problem or "".
std::string token_problem(std::string_view token);

}  // namespace tessera::server
