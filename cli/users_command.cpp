#include "cli/users_command.h"

#include "cli/exit_status.h"
#include "core/util/sha256.h"
#include "server/auth.h"
#include "server/user_file.h"

#include <spdlog/spdlog.h>

#include <algorithm>
#include <cstdio>
#include <stdexcept>

namespace tessera::cli {

CLI::App* add_users_command(CLI::App& app, UsersArgs& a) {
  auto* c = app.add_subcommand("users", "Manage the users file of a shared farm (serve --users FILE)");
  c->add_option("action", a.action,
                "add NAME: add a user and print its new token once, as the last line (only its hash is stored); "
                "ls: list the users; rm NAME: remove a user (a running coordinator forgets it on SIGHUP)")
      ->required()
      ->check(CLI::IsMember({"add", "ls", "rm"}));
  c->add_option("name", a.name, "The user's name (add, rm)");
  c->add_option("--users", a.file, "The users file (add makes it when missing)")->required();
  c->add_option("--role", a.role, "add: admin (everything), user (submit; control own jobs), viewer (read), worker "
                                  "(lease and upload)")
      ->check(CLI::IsMember({"admin", "user", "viewer", "worker"}))
      ->capture_default_str();
  c->add_option("--weight", a.weight, "add: the user's share of the farm against other users with work")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
  c->add_option("--max-workers", a.max_workers, "add: the user's tiles leased at once at most (0: no cap)")
      ->check(CLI::Range(int64_t(0), int64_t(1) << 30));
  return c;
}

int run_users(const UsersArgs& a) {
  try {
    if (a.action != "ls" && a.name.empty()) throw std::invalid_argument("users " + a.action + " needs a user name");
    std::vector<server::User> users = server::read_user_file(a.file, a.action == "add");
    if (a.action == "ls") {
      std::printf("%-24s %-8s %8s %12s\n", "NAME", "ROLE", "WEIGHT", "MAX_WORKERS");
      for (const server::User& u : users)
        std::printf("%-24s %-8s %8g %12s\n", u.name.c_str(), protocol::to_string(u.role), u.weight,
                    u.max_workers ? std::to_string(u.max_workers).c_str() : "-");
      return kExitOk;
    }
    const auto it = std::find_if(users.begin(), users.end(), [&](const server::User& u) { return u.name == a.name; });
    if (a.action == "rm") {
      if (it == users.end()) throw std::invalid_argument("no user '" + a.name + "' in " + a.file);
      users.erase(it);
      server::write_user_file(a.file, users);
      spdlog::info("removed user {} from {}; send the coordinator SIGHUP to apply it", a.name, a.file);
      return kExitOk;
    }
    if (const std::string p = server::user_name_problem(a.name); !p.empty()) throw std::invalid_argument(p);
    if (it != users.end()) throw std::invalid_argument("user '" + a.name + "' is already in " + a.file + " (rm it first)");
    const std::string token = server::generate_token();
    users.push_back({a.name, protocol::role_from_string(a.role), sha256_hex(token), a.weight, a.max_workers});
    server::write_user_file(a.file, users);
    spdlog::info("added {} ({}) to {}; send the coordinator SIGHUP to apply it. Its token follows; it is shown only "
                 "now:", a.name, a.role, a.file);
    std::printf("%s\n", token.c_str());
    return kExitOk;
  } catch (const std::exception& e) {
    spdlog::error("users {}: {}", a.action, e.what());
    return kExitRefused;
  }
}

}  // namespace tessera::cli
