// Who a request comes from and whether it may do what it asks: the configured tokens and users (server/user_file.h),
// each request's credential resolved to a caller (a user and its role) and checked against its method's access
// (protocol/access.h). Tokens are compared as SHA-256 digests in constant time and never logged.
#pragma once

#include "core/util/sha256.h"
#include "protocol/access.h"
#include "protocol/routes.h"
#include "server/user_file.h"

#include <filesystem>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

namespace tessera::server {

/// The credential each request must carry (each route's, protocol/routes.h).
using Access = protocol::Access;

/// The configured credentials; a side with none leaves its endpoints open (allowed on loopback only).
struct AccessTokens {
  std::string client;  ///< Token clients present: an admin named "client".
  std::string worker;  ///< Token workers present: a worker named "worker".
  std::filesystem::path users_file;  ///< Named users with roles and token digests (empty: none).
};

/// Who made a request.
struct Caller {
  std::string user{kOpenUser};                ///< Its user name.
  protocol::Role role = protocol::Role::admin;  ///< Its role.
};

/// Outcome of checking a request's credentials.
struct AuthDecision {
  enum Status { allowed, missing, invalid, wrong_role } status = allowed;  ///< Missing/invalid: 401; wrong_role: 403.
  std::string reason;      ///< Text for the error body; never contains a token.
  Caller caller;           ///< The caller (when allowed or wrong_role).
  std::string credential;  ///< Which credential it was, for Credentials::admits ("open", "client", "worker", ...).
};

/// The configured tokens and users. Thread-safe; the users file is read at construction and by reload().
class Credentials {
 public:
  /// Keeps the tokens' digests and reads the users file; throws std::runtime_error for a bad users file.
  explicit Credentials(const AccessTokens& tokens);
  /// Resolves and checks a request's credential: its Authorization header value ("Bearer <token>", possibly empty)
  /// or, without one, the subject (common name) of its verified client certificate naming a user. A side with no
  /// credential configured is open (its caller: "local", an admin; or "worker").
  AuthDecision authorize(Access need, std::string_view authorization, std::string_view cert_subject = {}) const;
  /// True while `credential` (an AuthDecision's) is still configured and its role still admits `need` (an open event
  /// stream is closed once its user is removed or loses the role).
  bool admits(const std::string& credential, Access need) const;
  /// Re-reads the users file (none: nothing to do) and returns how many users it holds; throws std::runtime_error
  /// keeping the users it had.
  size_t reload();
  /// The users as last read.
  std::vector<User> users() const;
  /// True when the client side and the worker side each need a credential (listening beyond loopback requires it).
  bool complete() const;
  /// True when the client side needs no credential.
  bool client_open() const;

 private:
  struct Users;  // the users file's contents, by token digest and by name
  std::shared_ptr<const Users> users_snapshot() const;

  std::optional<Sha256Digest> client_, worker_;
  std::filesystem::path users_file_;
  mutable std::mutex mu_;
  std::shared_ptr<const Users> users_;  // (mu_) replaced whole by reload()
};

/// Credentials(tokens).authorize(need, authorization).
AuthDecision authorize(Access need, std::string_view authorization, const AccessTokens& tokens);

/// Equality of two secrets in time independent of where they differ and of their lengths (compares SHA-256 digests).
bool constant_time_equal(std::string_view a, std::string_view b);

/// A fresh token from the operating system's cryptographic random source: 48 lowercase hex digits (192 bits).
std::string generate_token();

/// Checks that a token is usable (16 to 4096 printable ASCII characters without spaces); returns the problem or "".
std::string token_problem(std::string_view token);

}  // namespace tessera::server
