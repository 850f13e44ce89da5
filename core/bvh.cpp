#include "core/bvh.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_invoke.h>
#include <tbb/parallel_reduce.h>

#include <algorithm>
#include <array>
#include <atomic>
#include <cassert>
#include <functional>
#include <stdexcept>

namespace tessera {

namespace {

constexpr int kMaxBins = 32;
constexpr size_t kParallelBinThreshold = 64 * 1024;  // refs; below this binning runs on one thread
constexpr size_t kParallelTaskThreshold = 4 * 1024;  // refs; below this subtrees build on one thread
constexpr int kForceMedianDepth = 40;  // past this depth, split at the object median so depth stays bounded

struct BuildRef {
  Bounds3 box;
  Vec3 c;  // box centroid
  uint32_t id;
};

struct BuildNode {
  Bounds3 box;
  uint32_t left = 0, right = 0;  // child BuildNode indices (interior)
  uint32_t first = 0, count = 0;  // ref range (leaf when count > 0)
  uint8_t axis = 0;
};

struct Bin {
  Bounds3 box;
  uint32_t count = 0;
};

struct Bins {
  std::array<std::array<Bin, kMaxBins>, 3> b{};
  void merge(const Bins& o, int nb) {
    for (int a = 0; a < 3; ++a)
      for (int i = 0; i < nb; ++i) {
        b[a][i].box.extend(o.b[a][i].box);
        b[a][i].count += o.b[a][i].count;
      }
  }
};

// Maps a centroid coordinate to its bin; identical arithmetic in binning and partitioning.
struct BinMapper {
  Vec3 lo;
  Vec3 scale;  // nb / extent, 0 on flat axes
  int nb;
  int bin(const Vec3& c, int axis) const {
    const int k = int((c[axis] - lo[axis]) * scale[axis]);
    return std::clamp(k, 0, nb - 1);
  }
};

}  // namespace

struct Bvh::Builder {
  const BvhOptions& opt;
  std::vector<BuildRef>& refs;
  std::vector<BuildNode> nodes;
  std::atomic<uint32_t> next_node{0};

  Builder(const BvhOptions& o, std::vector<BuildRef>& r) : opt(o), refs(r), nodes(std::max<size_t>(1, 2 * r.size())) {}

  uint32_t alloc() { return next_node.fetch_add(1, std::memory_order_relaxed); }

  Bins bin_range(const BinMapper& m, size_t begin, size_t end) const {
    auto body = [&](const tbb::blocked_range<size_t>& r, Bins acc) {
      for (size_t i = r.begin(); i != r.end(); ++i)
        for (int a = 0; a < 3; ++a) {
          Bin& bin = acc.b[a][m.bin(refs[i].c, a)];
          bin.box.extend(refs[i].box);
          ++bin.count;
        }
      return acc;
    };
    if (end - begin < kParallelBinThreshold) return body(tbb::blocked_range<size_t>(begin, end), Bins{});
    return tbb::parallel_reduce(
        tbb::blocked_range<size_t>(begin, end, 8 * 1024), Bins{}, body,
        [&](Bins x, const Bins& y) { x.merge(y, m.nb); return x; });
  }

  void make_leaf(uint32_t idx, const Bounds3& box, size_t begin, size_t end) {
    BuildNode& n = nodes[idx];
    n.box = box;
    n.first = uint32_t(begin);
    n.count = uint32_t(end - begin);
  }

  // Builds the subtree over refs[begin, end) into node idx.
  void build(uint32_t idx, size_t begin, size_t end, int depth) {
    Bounds3 box, cbox;
    for (size_t i = begin; i < end; ++i) {
      box.extend(refs[i].box);
      cbox.extend(refs[i].c);
    }
    const size_t n = end - begin;
    if (n == 1) return make_leaf(idx, box, begin, end);

    const int axis = cbox.max_extent();
    const size_t max_leaf = size_t(std::clamp(opt.max_leaf_prims, 1, 255));
    int split_axis = axis;
    size_t mid = begin + n / 2;
    bool leaf = false;
    const Vec3 ext = cbox.diagonal();

    if (!(ext[axis] > 0.f)) {
      // All centroids coincide: no split separates them; a small set becomes a leaf, a large one is halved.
      leaf = n <= max_leaf;
    } else if (opt.split == SplitMethod::kMedian || depth >= kForceMedianDepth) {
      leaf = n <= max_leaf;
      if (!leaf) {
        std::nth_element(refs.begin() + begin, refs.begin() + mid, refs.begin() + end,
                         [axis](const BuildRef& x, const BuildRef& y) { return x.c[axis] < y.c[axis]; });
      }
    } else {
      const int nb = std::clamp(opt.bins, 2, kMaxBins);
      BinMapper m{cbox.lo, Vec3(0.f), nb};
      for (int a = 0; a < 3; ++a) m.scale[a] = ext[a] > 0.f ? float(nb) / ext[a] * (1.f - 1e-6f) : 0.f;
      const Bins bins = bin_range(m, begin, end);

      float best_cost = kInfinity;
      int best_axis = -1, best_split = 0;
      for (int a = 0; a < 3; ++a) {
        if (!(ext[a] > 0.f)) continue;
        std::array<float, kMaxBins> right_cost{};
        Bounds3 acc;
        uint32_t cnt = 0;
        for (int i = nb - 1; i > 0; --i) {
          acc.extend(bins.b[a][i].box);
          cnt += bins.b[a][i].count;
          right_cost[i] = cnt * acc.surface_area();
        }
        acc = Bounds3{};
        cnt = 0;
        for (int i = 0; i < nb - 1; ++i) {
          acc.extend(bins.b[a][i].box);
          cnt += bins.b[a][i].count;
          if (cnt == 0 || cnt == n) continue;
          const float cost = cnt * acc.surface_area() + right_cost[i + 1];
          if (cost < best_cost) { best_cost = cost; best_axis = a; best_split = i + 1; }
        }
      }
      const float area = box.surface_area();
      const float split_cost = 1.f + (area > 0.f ? best_cost / area : 0.f);
      const float leaf_cost = float(n);
      if (best_axis < 0) {
        leaf = n <= max_leaf;
      } else if (n <= max_leaf && leaf_cost <= split_cost) {
        leaf = true;
      } else {
        auto it = std::partition(refs.begin() + begin, refs.begin() + end,
                                 [&](const BuildRef& r) { return m.bin(r.c, best_axis) < best_split; });
        mid = size_t(it - refs.begin());
        if (mid == begin || mid == end) mid = begin + n / 2;  // unreachable with exact binning; stay safe
        split_axis = best_axis;
      }
    }

    if (leaf) return make_leaf(idx, box, begin, end);
    BuildNode& node = nodes[idx];
    node.box = box;
    node.axis = uint8_t(split_axis);
    node.left = alloc();
    node.right = alloc();
    const uint32_t l = node.left, r = node.right;
    if (n > kParallelTaskThreshold) {
      tbb::parallel_invoke([&] { build(l, begin, mid, depth + 1); }, [&] { build(r, mid, end, depth + 1); });
    } else {
      build(l, begin, mid, depth + 1);
      build(r, mid, end, depth + 1);
    }
  }
};

Bvh Bvh::build(std::span<const Triangle> triangles, std::span<const Sphere> spheres, const BvhOptions& options) {
  Bvh bvh;
  if (triangles.size() + spheres.size() >= (size_t(1) << 31)) throw std::length_error("Bvh: too many primitives");
  bvh.num_triangles_ = uint32_t(triangles.size());
  bvh.num_spheres_ = uint32_t(spheres.size());

  // Degenerate triangles and empty spheres can never be hit; leaving them out keeps boxes tight.
  std::vector<BuildRef> refs;
  refs.reserve(triangles.size() + spheres.size());
  for (uint32_t i = 0; i < triangles.size(); ++i) {
    const Triangle& t = triangles[i];
    if (is_degenerate(t)) continue;
    BuildRef r;
    r.box.extend(t.p0);
    r.box.extend(t.p1);
    r.box.extend(t.p2);
    r.c = r.box.centroid();
    r.id = i;
    refs.push_back(r);
  }
  for (uint32_t i = 0; i < spheres.size(); ++i) {
    const Sphere& s = spheres[i];
    if (!(s.radius > 0.f) || !std::isfinite(s.radius) || !is_finite(s.center)) continue;
    BuildRef r;
    r.box = Bounds3{s.center - Vec3(s.radius), s.center + Vec3(s.radius)};
    r.c = s.center;
    r.id = bvh.num_triangles_ + i;
    refs.push_back(r);
  }
  if (refs.empty()) return bvh;

  Builder b(options, refs);
  const uint32_t root = b.alloc();
  b.build(root, 0, refs.size(), 0);

  // Flatten depth-first: the first child directly follows its parent.
  bvh.nodes_.reserve(b.next_node.load());
  std::function<void(uint32_t)> emit = [&](uint32_t i) {
    const BuildNode& n = b.nodes[i];
    const uint32_t at = uint32_t(bvh.nodes_.size());
    bvh.nodes_.push_back(Node{n.box.lo, n.first, n.box.hi, uint16_t(n.count), n.axis, 0});
    if (n.count > 0) return;
    emit(n.left);
    bvh.nodes_[at].offset = uint32_t(bvh.nodes_.size());
    emit(n.right);
  };
  emit(root);

  bvh.prims_.resize(refs.size());
  bvh.prim_ids_.resize(refs.size());
  for (size_t i = 0; i < refs.size(); ++i) {
    const uint32_t id = refs[i].id;
    bvh.prim_ids_[i] = id;
    if (id < bvh.num_triangles_) {
      const Triangle& t = triangles[id];
      bvh.prims_[i] = PrimData{t.p0, t.p1, t.p2};
    } else {
      const Sphere& s = spheres[id - bvh.num_triangles_];
      bvh.prims_[i] = PrimData{s.center, Vec3(s.radius, 0.f, 0.f), Vec3(0.f)};
    }
  }
  return bvh;
}

std::optional<Hit> Bvh::intersect(const Ray& ray) const {
  if (nodes_.empty() || !ray.valid()) return std::nullopt;
  const BoxRay br(ray);
  const WatertightRay wr(ray);
  const bool neg[3] = {br.inv_d.x < 0.f, br.inv_d.y < 0.f, br.inv_d.z < 0.f};
  float tmax = ray.tmax;
  Hit best{};
  bool found = false;

  uint32_t stack[kMaxDepth];
  int sp = 0;
  uint32_t idx = 0;
  for (;;) {
    const Node& n = nodes_[idx];
    float tentry;
    if (slab_test(Bounds3{n.lo, n.hi}, br, tmax, &tentry)) {
      if (n.count > 0) {
        for (uint32_t i = n.offset, e = n.offset + n.count; i < e; ++i) {
          const PrimData& p = prims_[i];
          const uint32_t id = prim_ids_[i];
          if (id < num_triangles_) {
            if (auto h = intersect_triangle(wr, tmax, p.a, p.b, p.c)) {
              tmax = h->t;
              best = Hit{h->t, h->b1, h->b2, id};
              found = true;
            }
          } else if (auto t = intersect_sphere(Sphere{p.a, p.b.x}, ray, tmax)) {
            tmax = *t;
            best = Hit{*t, 0.f, 0.f, id};
            found = true;
          }
        }
        if (sp == 0) break;
        idx = stack[--sp];
      } else if (neg[n.axis]) {
        stack[sp++] = idx + 1;
        idx = n.offset;
      } else {
        stack[sp++] = n.offset;
        idx = idx + 1;
      }
    } else {
      if (sp == 0) break;
      idx = stack[--sp];
    }
  }
  if (!found) return std::nullopt;
  return best;
}

bool Bvh::occluded(const Ray& ray) const {
  if (nodes_.empty() || !ray.valid()) return false;
  const BoxRay br(ray);
  const WatertightRay wr(ray);
  const float tmax = ray.tmax;
  uint32_t stack[kMaxDepth];
  int sp = 0;
  uint32_t idx = 0;
  for (;;) {
    const Node& n = nodes_[idx];
    float tentry;
    if (slab_test(Bounds3{n.lo, n.hi}, br, tmax, &tentry)) {
      if (n.count > 0) {
        for (uint32_t i = n.offset, e = n.offset + n.count; i < e; ++i) {
          const PrimData& p = prims_[i];
          if (prim_ids_[i] < num_triangles_) {
            if (intersect_triangle(wr, tmax, p.a, p.b, p.c)) return true;
          } else if (intersect_sphere(Sphere{p.a, p.b.x}, ray, tmax)) {
            return true;
          }
        }
        if (sp == 0) break;
        idx = stack[--sp];
      } else {
        stack[sp++] = n.offset;
        idx = idx + 1;
      }
    } else {
      if (sp == 0) break;
      idx = stack[--sp];
    }
  }
  return false;
}

BvhStats Bvh::stats() const {
  BvhStats s;
  s.nodes = nodes_.size();
  if (nodes_.empty()) return s;
  const double root_area = Bounds3{nodes_[0].lo, nodes_[0].hi}.surface_area();
  struct Item { uint32_t idx; int depth; };
  std::vector<Item> todo{{0, 0}};
  double cost = 0.0;
  while (!todo.empty()) {
    const Item it = todo.back();
    todo.pop_back();
    const Node& n = nodes_[it.idx];
    const double rel = root_area > 0 ? Bounds3{n.lo, n.hi}.surface_area() / root_area : 1.0;
    if (n.count > 0) {
      ++s.leaves;
      s.max_depth = std::max(s.max_depth, it.depth);
      cost += rel * n.count;
    } else {
      cost += rel;
      todo.push_back({it.idx + 1, it.depth + 1});
      todo.push_back({n.offset, it.depth + 1});
    }
  }
  s.sah_cost = cost;
  return s;
}

}  // namespace tessera
