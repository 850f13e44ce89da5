// `tessera users`: the users file of a shared farm (add a user and print its token once, list, remove).
#pragma once

#include <CLI/CLI.hpp>

#include <cstdint>
#include <string>

namespace tessera::cli {

/// Options of `tessera users`.
struct UsersArgs {
  std::string action;        ///< add, ls or rm.
  std::string name;          ///< The user (add, rm).
  std::string role = "user"; ///< add: admin, user, viewer or worker.
  std::string file;          ///< The users file.
  double weight = 1;         ///< add: its share of the farm.
  int64_t max_workers = 0;   ///< add: its tiles leased at once at most (0: no cap).
};

/// Registers the subcommand's options on `app`.
CLI::App* add_users_command(CLI::App& app, UsersArgs& args);

/// Runs it; returns the process exit code: 0 done, 2 refused (bad name, role or file; a user that exists or not).
int run_users(const UsersArgs& args);

}  // namespace tessera::cli
