#include "cli/render_resume.h"

#include "cli/exit_status.h"

#include <charconv>
#include <stdexcept>

namespace tessera::cli {

namespace {

// The text of metadata key `key`, or an error naming the file.
const std::string& meta(const ExrImage& file, const std::string& path, const std::string& key) {
  const auto it = file.metadata.find(key);
  if (it == file.metadata.end())
    throw Refusal(path + " has no " + key + " metadata: it was not written by `tessera render`");
  return it->second;
}

template <class T>
T number(const ExrImage& file, const std::string& path, const std::string& key) {
  const std::string& text = meta(file, path, key);
  T v{};
  const auto r = std::from_chars(text.data(), text.data() + text.size(), v);
  if (r.ec != std::errc() || r.ptr != text.data() + text.size())
    throw Refusal(path + ": metadata " + key + " is not a number (\"" + text + "\")");
  return v;
}

}  // namespace

uint32_t recorded_spp(const ExrImage& file) {
  const auto it = file.metadata.find("tessera:spp");
  if (it == file.metadata.end() || it->second == "adaptive") return 0;
  return number<uint32_t>(file, "", "tessera:spp");
}

RenderArgs resumed_args(const RenderArgs& given, const ExrImage& file) {
  const std::string& path = given.resume;
  RenderArgs a = given;
  a.seed = number<uint64_t>(file, path, "tessera:seed");
  a.replicates = number<uint32_t>(file, path, "tessera:replicates");
  const std::string& spp = meta(file, path, "tessera:spp");
  if (spp == "adaptive") {
    if (given.spp)
      throw Refusal(path + " is an adaptive (--target-error) render: each pixel stopped on its own error "
                           "rule, so it can be finished but not refined with --spp");
    a.target_error = number<float>(file, path, "tessera:targetError");
    a.min_spp = number<uint32_t>(file, path, "tessera:minSpp");
    a.max_spp = number<uint32_t>(file, path, "tessera:maxSpp");
    a.error_floor = number<float>(file, path, "tessera:errorFloor");
  } else {
    const uint32_t stored = number<uint32_t>(file, path, "tessera:spp");
    if (given.spp && *given.spp < stored)
      throw Refusal(path + " was rendered at " + std::to_string(stored) + " spp; --spp " +
                    std::to_string(*given.spp) + " cannot take samples away");
    a.spp = given.spp ? *given.spp : stored;
  }
  const auto override_of = [&](const char* key) {
    const auto it = file.metadata.find(key);
    return it == file.metadata.end() ? std::string() : it->second;
  };
  a.area_sampling = override_of("tessera:areaSamplingOverride");
  a.env_sampling = override_of("tessera:envSamplingOverride");
  a.bvh = override_of("tessera:bvhOverride");
  a.layers = override_of("tessera:layers");
  const PixelWindow& w = file.data_window;
  a.crop = {w.x0, w.y0, w.x1, w.y1};
  a.variance = file.pixels.extra.count("variance.R") > 0;
  return a;
}

}  // namespace tessera::cli
