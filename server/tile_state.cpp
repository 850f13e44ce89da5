#include "server/tile_state.h"

#include "core/render/render_state.h"

#include <algorithm>
#include <bit>
#include <stdexcept>

namespace tessera::server {

std::optional<std::string> check_tile_state(const Image& tile, uint32_t spp, uint32_t replicates) {
  RenderState state;
  try {
    state = read_state_channels(tile, replicates);
  } catch (const std::exception& e) {
    return std::string("a resumable job's tile needs its exact sums: ") + e.what();
  }
  if (!state.exact())
    return std::string("a resumable job's tile needs its exact sums: no ") + kStateChannelPrefix + "* channels";
  for (size_t i = 0; i < state.samples.size(); ++i) {
    const int x = int(i % size_t(tile.width)), y = int(i / size_t(tile.width));
    const auto where = [&] { return " at tile pixel (" + std::to_string(x) + ", " + std::to_string(y) + ")"; };
    if (state.samples[i] != spp)
      return std::to_string(state.samples[i]) + " samples" + where() + ", the job has " + std::to_string(spp) + " spp";
    const Vec3 mean = state.pixel(i).estimate().mean;
    const Vec3 colour = tile.at(x, y);
    for (int c = 0; c < 3; ++c)
      if (std::bit_cast<uint32_t>(mean[c]) != std::bit_cast<uint32_t>(colour[c]))
        return "the colour" + where() + " is not the mean of its stored sums";
  }
  return std::nullopt;
}

std::map<std::string, std::vector<uint32_t>> result_state_channels(JobStore& store, const std::string& job,
                                                                   const TileGrid& grid, uint32_t spp,
                                                                   uint32_t replicates) {
  // The tiles' state channels are copied as stored (each tile checked first), so the whole image's sums are never
  // held as doubles besides.
  const size_t width = size_t(grid.width), pixels = width * size_t(grid.height);
  std::vector<std::string> channels{kSamplesChannel};
  for (const std::string& v : PixelAccumulator::state_names(replicates))
    for (const char* half : {".hi", ".lo"}) channels.push_back(kStateChannelPrefix + v + half);
  std::map<std::string, std::vector<uint32_t>> out;
  for (int64_t t = 0; t < grid.count(); ++t) {
    const auto stored = store.tile_state(job, t);
    const std::string name = "tile " + std::to_string(t);
    if (!stored) throw std::runtime_error(name + " has no stored state");
    if (stored->first != spp)
      throw std::runtime_error(name + "'s stored state has " + std::to_string(stored->first) + " spp, not " +
                               std::to_string(spp));
    const ExrImage exr = decode_exr(stored->second);
    const PixelWindow w = grid.window(t);
    if (!(exr.data_window == w)) throw std::runtime_error(name + "'s stored state covers another window");
    if (const auto why = check_tile_state(exr.pixels, spp, replicates)) throw std::runtime_error(name + ": " + *why);
    for (const std::string& channel : channels) {
      const std::vector<uint32_t>& values = exr.pixels.uint_extra.at(channel);  // there: checked above
      std::vector<uint32_t>& all = out[channel];
      all.resize(pixels);
      for (int y = 0; y < w.height(); ++y)
        std::copy_n(values.begin() + std::ptrdiff_t(size_t(y) * size_t(w.width())), w.width(),
                    all.begin() + std::ptrdiff_t(size_t(w.y0 + y) * width + size_t(w.x0)));
    }
  }
  return out;
}

}  // namespace tessera::server
