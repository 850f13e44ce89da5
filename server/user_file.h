// The users file of a shared farm (`serve --users FILE`, `tessera users`): each user's name, role, the SHA-256 of
// its token (the token itself is shown once, when the user is added, and stored nowhere), its weight in the fair
// share and its cap on tiles leased at once. docs/operations.md, "Running a shared farm", describes the format.
#pragma once

#include "protocol/access.h"

#include <cstdint>
#include <filesystem>
#include <string>
#include <string_view>
#include <vector>

namespace tessera::server {

/// One user.
struct User {
  std::string name;                        ///< Its name: jobs' owner, the audit trail's "who".
  protocol::Role role = protocol::Role::user;  ///< What it may do.
  std::string token_sha256;                ///< SHA-256 of its token, 64 lowercase hex digits.
  double weight = 1;                       ///< Its share of the farm relative to other users with work (> 0).
  int64_t max_workers = 0;                 ///< Its tiles leased at once at most; 0: no cap.
};

/// The user the client token (`serve --client-token-file`) stands for: an admin.
inline constexpr std::string_view kClientTokenUser = "client";
/// The user the worker token stands for.
inline constexpr std::string_view kWorkerTokenUser = "worker";
/// The caller of a coordinator whose client side needs no credential (on loopback): an admin.
inline constexpr std::string_view kOpenUser = "local";

/// The problem with a user name (1 to 64 of a-z, A-Z, 0-9, '.', '_', '-', starting with a letter or digit, none of
/// the three above), or "".
std::string user_name_problem(std::string_view name);

/// Reads and checks a users file (a missing file is an empty list only when `missing_ok`); throws std::runtime_error
/// with a sentence naming the file and the entry.
std::vector<User> read_user_file(const std::filesystem::path& file, bool missing_ok = false);
/// Replaces the users file atomically (readable by its owner only); throws std::runtime_error naming it.
void write_user_file(const std::filesystem::path& file, const std::vector<User>& users);

}  // namespace tessera::server
