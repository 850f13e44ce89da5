#include "server/tile_state.h"

#include "core/render_state.h"

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
  const PixelWindow full{0, 0, grid.width, grid.height};
  const size_t m = PixelAccumulator::state_size(replicates);
  RenderState all;
  all.replicates = replicates;
  all.samples.assign(size_t(full.width()) * size_t(full.height()), 0);
  all.sums.assign(all.samples.size() * m, 0.0);
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
    const RenderState part = read_state_channels(exr.pixels, replicates);
    if (!part.exact()) throw std::runtime_error(name + "'s stored state has no exact sums");
    for (int y = 0; y < w.height(); ++y)
      for (int x = 0; x < w.width(); ++x) {
        const size_t from = size_t(y) * size_t(w.width()) + size_t(x);
        const size_t to = size_t(w.y0 + y) * size_t(full.width()) + size_t(w.x0 + x);
        all.samples[to] = part.samples[from];
        std::copy_n(part.sums.begin() + std::ptrdiff_t(from * m), m, all.sums.begin() + std::ptrdiff_t(to * m));
      }
  }
  Image channels = Image::make(full.width(), full.height());
  write_state_channels(all, channels);
  return std::move(channels.uint_extra);
}

}  // namespace tessera::server
