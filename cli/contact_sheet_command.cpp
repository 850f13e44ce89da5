#include "cli/contact_sheet_command.h"

#include "cli/exit_status.h"
#include "cli/output_check.h"
#include "core/image/contact_sheet.h"
#include "core/image/image.h"

#include <spdlog/spdlog.h>

#include <cstdio>

namespace tessera::cli {

CLI::App* add_contact_sheet_command(CLI::App& app, ContactSheetArgs& a) {
  auto* c = app.add_subcommand("contact-sheet", "Lay out a sequence's frames (EXR files) as small copies in one PNG");
  c->add_option("frames", a.inputs, "EXR files, in the order to lay them out (e.g. out/frame_*.exr)")
      ->required()
      ->check(CLI::ExistingFile);
  c->add_option("-o,--output", a.output, "PNG file to write (sRGB, tone-mapped as --preview)")->required();
  c->add_option("--thumb-width", a.thumb_width, "Width of each small copy in pixels")
      ->check(CLI::Range(1, 4096))->capture_default_str();
  c->add_option("--columns", a.columns, "Copies per row (0: a near-square grid)")
      ->check(CLI::Range(0, 4096))->capture_default_str();
  c->footer("Each file is read and shrunk (box filter) before the next is read, so only the small copies are held.");
  return c;
}

int run_contact_sheet(const ContactSheetArgs& a) {
  if (!output_writable(a.output)) return kExitRefused;
  std::vector<Image> thumbs;
  thumbs.reserve(a.inputs.size());
  for (const std::string& path : a.inputs) {
    try {
      ExrReadOptions ro;
      ro.colour_only = true;
      thumbs.push_back(thumbnail(read_exr(path, ro).pixels, a.thumb_width));
    } catch (const std::exception& e) {
      spdlog::error("{}: {}", path, e.what());
      return kExitRefused;
    }
  }
  Image sheet;
  try {
    sheet = contact_sheet(thumbs, a.columns);
    write_png_srgb(a.output, sheet);
  } catch (const std::exception& e) {
    spdlog::error("contact-sheet failed: {}", e.what());
    return kExitFailed;
  }
  std::fprintf(stderr, "%s: %zu frames, %dx%d px\n", a.output.c_str(), thumbs.size(), sheet.width, sheet.height);
  return kExitOk;
}

}  // namespace tessera::cli
