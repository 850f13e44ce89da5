#include "core/geometry/bounds.h"

namespace tessera {

std::optional<BoxInterval> intersect_box(const Bounds3& b, const Ray& r) {
  if (!r.valid() || b.empty()) return std::nullopt;
  float t0 = 0.f, t1 = r.tmax;
  for (int a = 0; a < 3; ++a) {
    const float inv = 1.f / r.d[a];
    if (std::isinf(inv)) {
      // Parallel to this slab (or a component too small to invert): inside the closed slab or a miss.
      if (r.o[a] < b.lo[a] || r.o[a] > b.hi[a]) return std::nullopt;
      continue;
    }
    float tn = (b.lo[a] - r.o[a]) * inv;
    float tf = (b.hi[a] - r.o[a]) * inv;
    if (tn > tf) std::swap(tn, tf);
    tf *= 1.f + 2.f * gamma(3);
    t0 = std::max(t0, tn);
    t1 = std::min(t1, tf);
    if (t0 > t1) return std::nullopt;
  }
  return BoxInterval{t0, t1};
}

}  // namespace tessera
