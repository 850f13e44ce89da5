#include "core/render/render_state.h"

#include <bit>
#include <string>

namespace tessera {

PixelAccumulator RenderState::pixel(size_t i) const {
  const size_t m = PixelAccumulator::state_size(replicates);
  return PixelAccumulator::restore(replicates, samples[i], sums.data() + i * m);
}

void RenderState::set(size_t i, const PixelAccumulator& acc) {
  samples[i] = acc.count();
  acc.save(sums.data() + i * PixelAccumulator::state_size(replicates));
}

void write_state_channels(const RenderState& state, Image& img, size_t first) {
  const size_t n = size_t(img.width) * size_t(img.height);
  if (first + n > state.samples.size())
    throw ImageError("write_state_channels: pixels " + std::to_string(first) + ".." + std::to_string(first + n) +
                     " are not all in a state of " + std::to_string(state.samples.size()));
  const auto samples = state.samples.begin() + std::ptrdiff_t(first);
  img.uint_extra[kSamplesChannel].assign(samples, samples + std::ptrdiff_t(n));
  if (!state.exact()) return;
  const std::vector<std::string> names = PixelAccumulator::state_names(state.replicates);
  for (size_t v = 0; v < names.size(); ++v) {
    std::vector<uint32_t>& hi = img.uint_extra[kStateChannelPrefix + names[v] + ".hi"];
    std::vector<uint32_t>& lo = img.uint_extra[kStateChannelPrefix + names[v] + ".lo"];
    hi.resize(n);
    lo.resize(n);
    for (size_t i = 0; i < n; ++i) {
      const uint64_t bits = std::bit_cast<uint64_t>(state.sums[(first + i) * names.size() + v]);
      hi[i] = uint32_t(bits >> 32);
      lo[i] = uint32_t(bits);
    }
  }
}

RenderState read_state_channels(const Image& img, uint32_t replicates) {
  const size_t n = size_t(img.width) * size_t(img.height);
  RenderState state;
  state.replicates = replicates;
  const auto channel = [&](const std::string& name) -> const std::vector<uint32_t>* {
    const auto it = img.uint_extra.find(name);
    if (it == img.uint_extra.end()) return nullptr;
    if (it->second.size() != n) throw ImageError("channel " + name + " does not cover the image");
    return &it->second;
  };
  const std::vector<uint32_t>* samples = channel(kSamplesChannel);
  if (!samples) throw ImageError(std::string("no ") + kSamplesChannel + " channel (not written by a resumable render)");
  state.samples = *samples;
  const std::vector<std::string> names = PixelAccumulator::state_names(replicates);
  size_t found = 0;
  for (const auto& [name, values] : img.uint_extra) found += name.starts_with(kStateChannelPrefix) ? 1 : 0;
  if (found == 0) return state;
  if (found != 2 * names.size())
    throw ImageError("accumulator channels: " + std::to_string(found) + " found, " + std::to_string(2 * names.size()) +
                     " expected for " + std::to_string(replicates) + " replicate(s)");
  state.sums.resize(n * names.size());
  for (size_t v = 0; v < names.size(); ++v) {
    const std::vector<uint32_t>* hi = channel(kStateChannelPrefix + names[v] + ".hi");
    const std::vector<uint32_t>* lo = channel(kStateChannelPrefix + names[v] + ".lo");
    if (!hi || !lo) throw ImageError("accumulator channel " + std::string(kStateChannelPrefix) + names[v] + " is missing");
    for (size_t i = 0; i < n; ++i)
      state.sums[i * names.size() + v] = std::bit_cast<double>(uint64_t((*hi)[i]) << 32 | (*lo)[i]);
  }
  return state;
}

}  // namespace tessera
