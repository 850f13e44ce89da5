// `tessera contact-sheet`: a sequence's frames (EXR files) as one PNG of small copies in a grid.
#pragma once

#include <CLI/CLI.hpp>

#include <string>
#include <vector>

namespace tessera::cli {

/// Options of `tessera contact-sheet`.
struct ContactSheetArgs {
  std::vector<std::string> inputs;  ///< EXR files, in the order they are laid out.
  std::string output;               ///< PNG to write.
  int thumb_width = 160;            ///< Width of each small copy.
  int columns = 0;                  ///< Copies per row (0: a near-square grid).
};

/// Registers the subcommand's options on `app`.
CLI::App* add_contact_sheet_command(CLI::App& app, ContactSheetArgs& args);

/// Runs it; returns the process exit code: 0 written, 2 an input that cannot be read (nothing written), 1 the write
/// failed.
int run_contact_sheet(const ContactSheetArgs& args);

}  // namespace tessera::cli
