#include "core/image/merge.h"

#include <algorithm>
#include <cstdio>
#include <cstring>
#include <utility>

namespace tessera {

std::string format_window(const PixelWindow& w) {
  char buf[96];
  std::snprintf(buf, sizeof buf, "[%d,%d) x [%d,%d)", w.x0, w.x1, w.y0, w.y1);
  return buf;
}

std::string format_regions(const std::vector<PixelWindow>& regions, size_t max_listed) {
  std::string out;
  int64_t pixels = 0;
  for (size_t i = 0; i < regions.size(); ++i) {
    pixels += int64_t(regions[i].width()) * regions[i].height();
    if (i >= max_listed) continue;
    if (i > 0) out += ", ";
    out += format_window(regions[i]);
  }
  if (regions.size() > max_listed) {
    out += " and ";
    out += std::to_string(regions.size() - max_listed);
    out += " more";
  }
  out += " (";
  out += std::to_string(pixels);
  out += pixels == 1 ? " pixel)" : " pixels)";
  return out;
}

std::vector<PixelWindow> mask_to_rectangles(const std::vector<uint8_t>& mask, const PixelWindow& frame) {
  const int w = frame.width(), h = frame.height();
  std::vector<PixelWindow> done;
  std::vector<PixelWindow> open;  // rectangles reaching the previous row, sorted by x0
  for (int y = 0; y < h; ++y) {
    std::vector<PixelWindow> runs;
    for (int x = 0; x < w;) {
      if (!mask[size_t(y) * size_t(w) + size_t(x)]) {
        ++x;
        continue;
      }
      const int start = x;
      while (x < w && mask[size_t(y) * size_t(w) + size_t(x)]) ++x;
      runs.push_back({frame.x0 + start, frame.y0 + y, frame.x0 + x, frame.y0 + y + 1});
    }
    std::vector<PixelWindow> next;
    size_t o = 0;
    for (PixelWindow r : runs) {
      while (o < open.size() && open[o].x0 < r.x0) done.push_back(open[o++]);
      if (o < open.size() && open[o].x0 == r.x0 && open[o].x1 == r.x1) {
        r.y0 = open[o++].y0;  // the same run as the row above: extend that rectangle
      }
      next.push_back(r);
    }
    while (o < open.size()) done.push_back(open[o++]);
    open = std::move(next);
  }
  done.insert(done.end(), open.begin(), open.end());
  std::sort(done.begin(), done.end(), [](const PixelWindow& a, const PixelWindow& b) {
    return std::pair(a.y0, a.x0) < std::pair(b.y0, b.x0);
  });
  return done;
}

namespace {

PixelWindow intersect(const PixelWindow& a, const PixelWindow& b) {
  return {std::max(a.x0, b.x0), std::max(a.y0, b.y0), std::min(a.x1, b.x1), std::min(a.y1, b.y1)};
}

// The names of an image's float extra channels, comma-separated ("none" when it has none).
std::string channel_list(const Image& img) {
  std::string out;
  for (const auto& entry : img.extra) out += (out.empty() ? "" : ", ") + entry.first;
  return out.empty() ? "none" : out;
}

}  // namespace

MergeResult merge_tiles(const std::vector<MergeInput>& inputs) {
  if (inputs.empty()) throw MergeError("cannot merge: no input tiles");
  const PixelWindow display = inputs[0].image.display_window;
  std::vector<std::string> problems;

  for (const MergeInput& in : inputs) {
    if (!(in.image.display_window == display)) {
      problems.push_back(in.name + " has display window " + format_window(in.image.display_window) + ", but " +
                         inputs[0].name + " has " + format_window(display));
    } else if (!display.contains(in.image.data_window)) {
      problems.push_back(in.name + " has data window " + format_window(in.image.data_window) +
                         " outside the display window " + format_window(display));
    } else if (in.image.pixels.width != in.image.data_window.width() ||
               in.image.pixels.height != in.image.data_window.height()) {
      problems.push_back(in.name + " has " + std::to_string(in.image.pixels.width) + "x" +
                         std::to_string(in.image.pixels.height) + " pixels for data window " +
                         format_window(in.image.data_window));
    } else if (channel_list(in.image.pixels) != channel_list(inputs[0].image.pixels)) {
      problems.push_back(in.name + " has extra channels " + channel_list(in.image.pixels) + ", but " +
                         inputs[0].name + " has " + channel_list(inputs[0].image.pixels));
    }
  }
  if (!problems.empty()) {
    std::string msg = "cannot merge " + std::to_string(inputs.size()) + " tiles:";
    for (const auto& p : problems) msg += "\n  " + p;
    throw MergeError(msg);
  }

  const int W = display.width(), H = display.height();
  MergeResult out;
  out.display_window = display;
  out.image = Image::make(W, H);
  // The float extra channels, merged like the colour: (output, input channel of the current tile) per channel.
  std::vector<std::pair<float*, const float*>> extra;
  for (const auto& entry : inputs[0].image.pixels.extra) {
    std::vector<float>& ch = out.image.extra[entry.first];
    ch.assign(size_t(W) * size_t(H), 0.f);
    extra.emplace_back(ch.data(), nullptr);
  }
  std::vector<int32_t> owner(size_t(W) * size_t(H), -1);
  // Conflicts per (first supplier, later supplier): a mask over the intersection of their data windows.
  std::map<std::pair<int32_t, int32_t>, std::vector<uint8_t>> conflicts;

  for (int32_t i = 0; i < int32_t(inputs.size()); ++i) {
    const ExrImage& tile = inputs[size_t(i)].image;
    const PixelWindow& dw = tile.data_window;
    size_t e = 0;
    for (const auto& entry : tile.pixels.extra) extra[e++].second = entry.second.data();
    for (int y = dw.y0; y < dw.y1; ++y) {
      for (int x = dw.x0; x < dw.x1; ++x) {
        const size_t dst = size_t(y - display.y0) * size_t(W) + size_t(x - display.x0);
        const size_t at = size_t(y - dw.y0) * size_t(dw.width()) + size_t(x - dw.x0);
        const float* src = &tile.pixels.rgb[3 * at];
        float* px = &out.image.rgb[3 * dst];
        if (owner[dst] < 0) {
          owner[dst] = i;
          std::memcpy(px, src, 3 * sizeof(float));
          for (const auto& [to, from] : extra) to[dst] = from[at];
          continue;
        }
        ++out.overlap_pixels;
        bool same = std::memcmp(px, src, 3 * sizeof(float)) == 0;
        for (const auto& [to, from] : extra) same = same && std::memcmp(&to[dst], &from[at], sizeof(float)) == 0;
        if (same) continue;
        const int32_t first = owner[dst];
        const PixelWindow both = intersect(inputs[size_t(first)].image.data_window, dw);
        auto& mask = conflicts[{first, i}];
        if (mask.empty()) mask.assign(size_t(both.width()) * size_t(both.height()), 0);
        mask[size_t(y - both.y0) * size_t(both.width()) + size_t(x - both.x0)] = 1;
      }
    }
  }

  std::vector<uint8_t> gaps(owner.size());
  bool any_gap = false;
  for (size_t p = 0; p < owner.size(); ++p) any_gap |= (gaps[p] = owner[p] < 0);
  if (any_gap)
    problems.push_back("pixels covered by no tile: " + format_regions(mask_to_rectangles(gaps, display)));
  for (const auto& [pair, mask] : conflicts) {
    const PixelWindow both =
        intersect(inputs[size_t(pair.first)].image.data_window, inputs[size_t(pair.second)].image.data_window);
    problems.push_back("conflicting overlap of " + inputs[size_t(pair.first)].name + " and " +
                       inputs[size_t(pair.second)].name + " (different values): " +
                       format_regions(mask_to_rectangles(mask, both)));
  }
  if (!problems.empty()) {
    std::string msg = "cannot merge " + std::to_string(inputs.size()) + " tiles into " + format_window(display) + ":";
    for (const auto& p : problems) msg += "\n  " + p;
    throw MergeError(msg);
  }

  out.metadata = inputs[0].image.metadata;
  for (size_t i = 1; i < inputs.size(); ++i)
    std::erase_if(out.metadata, [&](const auto& kv) {
      const auto it = inputs[i].image.metadata.find(kv.first);
      return it == inputs[i].image.metadata.end() || it->second != kv.second;
    });
  return out;
}

}  // namespace tessera
