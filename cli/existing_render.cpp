#include "cli/existing_render.h"

#include "core/render/layers.h"

#include "cli/sampling_flags.h"
#include "core/image/image.h"
#include "core/render/render_state.h"

#include <charconv>
#include <exception>
#include <optional>
#include <system_error>

namespace tessera::cli {

namespace fs = std::filesystem;

namespace {

// The reason in a read error, without the "cannot read EXR "path": " that names the file the caller names already.
std::string read_error(const std::exception& e) {
  const std::string what = e.what();
  const size_t colon = what.find("\": ");
  return what.rfind("cannot read EXR ", 0) == 0 && colon != std::string::npos ? what.substr(colon + 3) : what;
}

// A samples-per-pixel value as recorded ("adaptive" and malformed text give nullopt).
std::optional<uint32_t> spp_number(const std::string& text) {
  uint32_t v = 0;
  const auto r = std::from_chars(text.data(), text.data() + text.size(), v);
  if (r.ec != std::errc() || r.ptr != text.data() + text.size()) return std::nullopt;
  return v;
}

// The value of `key` in `m`, or "" when absent.
std::string value_of(const std::map<std::string, std::string>& m, const std::string& key) {
  const auto it = m.find(key);
  return it == m.end() ? std::string() : it->second;
}

}  // namespace

const std::set<std::string>& sampling_keys() {
  static const std::set<std::string> keys = [] {
    // Settings that make every key appear.
    protocol::SamplingSettings all;
    all.target_error = 1.0;
    all.area_sampling = all.env_sampling = all.bvh = "x";
    std::set<std::string> k;
    for (const auto& [key, value] : all.metadata()) k.insert(key);
    return k;
  }();
  return keys;
}

std::string sampling_difference(const std::map<std::string, std::string>& file,
                                const std::map<std::string, std::string>& expected, const std::string& ignored) {
  for (const std::string& key : sampling_keys()) {
    if (key == ignored) continue;
    const auto f = file.find(key), e = expected.find(key);
    const bool in_file = f != file.end(), in_expected = e != expected.end();
    if (!in_file && !in_expected) continue;
    if (in_file && in_expected && f->second == e->second) continue;
    return (in_file ? key + " " + f->second : "no " + key) + ", not " + (in_expected ? e->second : "none");
  }
  return "";
}

ExpectedRender expected_render(const RenderArgs& args, const std::string& scene_hash, int width, int height,
                               uint32_t scene_spp) {
  ExpectedRender e;
  e.scene_hash = scene_hash;
  e.width = width;
  e.height = height;
  e.sampling = sampling_settings(args, args.spp ? *args.spp : scene_spp).metadata();
  e.half = args.half;
  e.variance = args.variance || parse_layers(args.layers).has(Layer::kVariance);
  e.resumable = args.resumable;
  return e;
}

ExistingRender examine_render(const fs::path& path, const ExpectedRender& expected) {
  ExistingRender r;
  std::error_code ec;
  if (!fs::exists(fs::symlink_status(path, ec))) return r;
  r.exists = true;
  const auto neither = [&](const std::string& why) {
    r.complete = r.continuable = false;
    r.why_incomplete = r.why_not_continuable = why;
    return r;
  };
  ExrHeader h;
  try {
    h = read_exr_header(path);
  } catch (const std::exception& e) {
    return neither("does not read (" + read_error(e) + ")");
  }
  const std::map<std::string, std::string>& m = h.metadata;
  const auto hash = m.find("tessera:sceneHash");
  if (hash == m.end()) return neither("has no tessera:sceneHash metadata (it was not written by `tessera render`)");
  if (hash->second != expected.scene_hash) return neither("was rendered from another scene (or other assets)");
  const PixelWindow full{0, 0, expected.width, expected.height};
  if (h.display_window != full)
    return neither("is not a " + std::to_string(expected.width) + "x" + std::to_string(expected.height) + " picture");
  if (h.data_window != full)
    return neither("is a crop (pixels " + std::to_string(h.data_window.x0) + " " + std::to_string(h.data_window.y0) +
                   " " + std::to_string(h.data_window.x1) + " " + std::to_string(h.data_window.y1) + ")");

  const bool partial = m.count("tessera:partial") > 0;
  bool exact = false;
  for (const auto& [name, type] : h.channels) exact |= name.rfind(kStateChannelPrefix, 0) == 0;
  const auto colour = h.channels.find("R");
  const bool half = colour != h.channels.end() && colour->second == ExrPixelType::kHalf;
  // Variance channels are in the first part, or in a part of their own in a multi-part file (its tessera:layers says).
  const auto layers = m.find("tessera:layers");
  const bool variance = h.channels.count("variance.R") > 0 ||
                        (layers != m.end() && parse_layers(layers->second).has(Layer::kVariance));
  const std::string settings = sampling_difference(m, expected.sampling);
  const std::string settings_but_spp = sampling_difference(m, expected.sampling, "tessera:spp");
  const std::string variance_why = variance == expected.variance ? ""
                                   : variance ? "has variance channels (--variance)"
                                              : "has no variance channels (--variance)";

  if (!settings.empty()) r.why_incomplete = "was rendered with " + settings;
  else if (partial) r.why_incomplete = "is partial (" + m.at("tessera:partial") + ")";
  else if (half != expected.half)
    r.why_incomplete = half ? "holds half-float colours (--half)" : "holds float32 colours, not half floats (--half)";
  else if (!variance_why.empty()) r.why_incomplete = variance_why;
  else if (expected.resumable && !exact) r.why_incomplete = "holds no exact sample sums (--resumable)";
  r.complete = r.why_incomplete.empty();

  // What --resume accepts (cli/render_command.cpp, load_previous): the same settings but spp; a partial file finished
  // at its own spp, or raised with exact sums; a finished one raised with exact sums.
  const std::string file_spp = value_of(m, "tessera:spp"), want_spp = value_of(expected.sampling, "tessera:spp");
  const std::optional<uint32_t> have = spp_number(file_spp), want = spp_number(want_spp);
  if (!settings_but_spp.empty()) r.why_not_continuable = "was rendered with " + settings_but_spp;
  else if (!variance_why.empty()) r.why_not_continuable = variance_why;
  else if (file_spp == want_spp && !partial) r.why_not_continuable = r.complete ? "is complete" : r.why_incomplete;
  else if (have && want && *have > *want)
    r.why_not_continuable = "was rendered at " + file_spp + " spp, more than " + want_spp;
  else if (file_spp != want_spp && !exact)
    r.why_not_continuable = "holds no exact sample sums (--resumable), so it can only be finished at its own " +
                            file_spp + " spp";
  else if (expected.resumable && !exact)
    r.why_not_continuable = "holds no exact sample sums, so its continuation cannot be --resumable";
  r.continuable = r.why_not_continuable.empty();

  if (r.complete || r.continuable) {
    try {
      (void)read_exr(path);
    } catch (const std::exception& e) {
      return neither("does not read (" + read_error(e) + ")");
    }
  }
  return r;
}

}  // namespace tessera::cli
