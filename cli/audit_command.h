// `tessera audit`: the coordinator's audit trail (who did what to which job or worker, when and from where).
#pragma once

#include "cli/coordinator_access.h"

#include <CLI/CLI.hpp>

#include <cstddef>
#include <string>

namespace tessera::cli {

/// Options of `tessera audit`.
struct AuditArgs {
  std::string user;          ///< Only this user's actions.
  size_t limit = 100;        ///< Entries, newest first.
  int64_t before = 0;        ///< Only entries numbered below this (0: the newest).
  CoordinatorAccess access;  ///< Coordinator URL, token and TLS files.
};

/// Registers the subcommand's options on `app`.
CLI::App* add_audit_command(CLI::App& app, AuditArgs& args);

/// Runs it; returns the process exit code: 0 done, 2 refused (not an admin), 1 other errors.
int run_audit(const AuditArgs& args);

}  // namespace tessera::cli
