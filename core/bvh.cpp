#include "core/bvh.h"

#include <emmintrin.h>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/parallel_invoke.h>
#include <tbb/parallel_reduce.h>
#include <tbb/task_group.h>

#include <algorithm>
#include <array>
#include <atomic>
#include <bit>
#include <cassert>
#include <limits>
#include <cstdlib>
#include <stdexcept>

#if defined(__linux__)
#include <sys/mman.h>
#endif

namespace tessera {

namespace detail {

constexpr size_t kHugePage = size_t(2) << 20;

void* allocate_large(size_t bytes, size_t align) {
  if (bytes < kHugePage) return ::operator new(bytes, std::align_val_t(align));
  const size_t size = (bytes + kHugePage - 1) / kHugePage * kHugePage;
  void* p = std::aligned_alloc(kHugePage, size);
  if (!p) throw std::bad_alloc();
#if defined(__linux__) && defined(MADV_HUGEPAGE)
  ::madvise(p, size, MADV_HUGEPAGE);  // advice only: failure leaves ordinary pages
#endif
  return p;
}

void deallocate_large(void* p, size_t bytes, size_t align) noexcept {
  if (bytes < kHugePage) {
    ::operator delete(p, bytes, std::align_val_t(align));
  } else {
    std::free(p);
  }
}

}  // namespace detail

namespace {

constexpr int kMaxBins = 32;
constexpr size_t kParallelBinThreshold = 64 * 1024;  // refs; below this binning runs on one thread
constexpr size_t kParallelTaskThreshold = 4 * 1024;  // refs; below this subtrees build on one thread
constexpr int kForceMedianDepth = 40;  // binary split depth past which splits use the object median (bounded depth)
constexpr int kWidth = 4;              // children per node and primitives per packet

// SAH constants for the 4-wide tree with 4-wide leaf packets, in units of one packet (four primitives) test. A
// binary split becomes half of a 4-wide node on average, and a 4-box SSE slab test is cheaper than a 4-triangle
// watertight test.
constexpr float kTraversalCost = 0.5f;
constexpr float kPacketCost = 1.f;

inline uint32_t packets_for(uint32_t prims) { return (prims + kWidth - 1) / kWidth; }

// A build reference: the primitive's box with its id in lo's fourth lane, 32 bytes, loaded as two SSE vectors.
// Its "centroid" is lo + hi (twice the centre; only compared and binned, so the factor does not matter).
struct alignas(16) BuildRef {
  float lo[3];
  uint32_t id;
  float hi[3];
  uint32_t pad;
  __m128 vlo() const { return _mm_load_ps(lo); }
  __m128 vhi() const { return _mm_load_ps(hi); }
  __m128 c2() const { return _mm_add_ps(vlo(), vhi()); }
};
static_assert(sizeof(BuildRef) == 32);

using RefVector = std::vector<BuildRef, detail::UninitAllocator<BuildRef>>;

// An SSE box; only lanes 0-2 mean anything. Trivially constructible (bin arrays are not initialised twice): start
// from Box4::empty().
struct Box4 {
  __m128 lo, hi;
  static Box4 empty() { return Box4{_mm_set1_ps(kInfinity), _mm_set1_ps(-kInfinity)}; }
  void extend(__m128 l, __m128 h) {
    lo = _mm_min_ps(lo, l);
    hi = _mm_max_ps(hi, h);
  }
  void extend(const Box4& b) { extend(b.lo, b.hi); }
  void extend(__m128 p) { extend(p, p); }
  Bounds3 bounds() const {
    alignas(16) float l[4], h[4];
    _mm_store_ps(l, lo);
    _mm_store_ps(h, hi);
    return Bounds3{Vec3(l[0], l[1], l[2]), Vec3(h[0], h[1], h[2])};
  }
  float area() const {
    alignas(16) float d[4];
    _mm_store_ps(d, _mm_max_ps(_mm_sub_ps(hi, lo), _mm_setzero_ps()));  // 0 for an empty box
    return 2.f * (d[0] * d[1] + d[1] * d[2] + d[2] * d[0]);
  }
};

struct Bins {
  int nb;
  Box4 box[3][kMaxBins];
  uint32_t count[3][kMaxBins];
  explicit Bins(int n) : nb(n) {
    for (int a = 0; a < 3; ++a)
      for (int i = 0; i < nb; ++i) {
        box[a][i] = Box4::empty();
        count[a][i] = 0;
      }
  }
  void merge(const Bins& o) {
    for (int a = 0; a < 3; ++a)
      for (int i = 0; i < nb; ++i) {
        box[a][i].extend(o.box[a][i]);
        count[a][i] += o.count[a][i];
      }
  }
};

// Maps a centroid to its bin on each axis: trunc(clamp((c - lo) * scale, 0, nb - 1)), scale = nb / extent (0 on
// flat axes). Binning and partitioning both use this one function, so they agree exactly.
struct BinMapper {
  __m128 lo, scale, top;
  BinMapper(const Bounds3& cbox, int nb) {
    const Vec3 ext = cbox.diagonal();
    alignas(16) float s[4] = {0.f, 0.f, 0.f, 0.f};
    for (int a = 0; a < 3; ++a) s[a] = ext[a] > 0.f ? float(nb) / ext[a] * (1.f - 1e-6f) : 0.f;
    lo = _mm_setr_ps(cbox.lo.x, cbox.lo.y, cbox.lo.z, 0.f);
    scale = _mm_load_ps(s);
    top = _mm_set1_ps(float(nb - 1));
  }
  __m128i bins(__m128 c2) const {
    const __m128 f = _mm_mul_ps(_mm_sub_ps(c2, lo), scale);
    return _mm_cvttps_epi32(_mm_min_ps(_mm_max_ps(f, _mm_setzero_ps()), top));
  }
  int bin(__m128 c2, int axis) const {
    alignas(16) int k[4];
    _mm_store_si128(reinterpret_cast<__m128i*>(k), bins(c2));
    return k[axis];
  }
};

// A contiguous run of build references with its bounds, the bounds of its centroids (lo + hi) and its binary split
// depth.
struct Range {
  uint32_t begin = 0, end = 0;
  Bounds3 box, cbox;
  int depth = 0;
  uint32_t size() const { return end - begin; }
};

}  // namespace

struct Bvh::Builder {
  const BvhOptions& opt;
  RefVector& refs;
  std::span<const Triangle> triangles;
  std::span<const Sphere> spheres;
  Bvh& bvh;
  std::atomic<uint32_t> next_node{0};
  std::atomic<uint32_t> next_packet{0};

  Builder(const BvhOptions& o, RefVector& r, std::span<const Triangle> t, std::span<const Sphere> s, Bvh& b)
      : opt(o), refs(r), triangles(t), spheres(s), bvh(b) {}

  uint32_t leaf_limit() const { return uint32_t(std::clamp(opt.max_leaf_prims, 1, 255)); }

  void bin_into(Bins& acc, const BinMapper& m, size_t begin, size_t end) const {
    alignas(16) int k[4];
    for (size_t i = begin; i != end; ++i) {
      const BuildRef& ref = refs[i];
      const __m128 lo = ref.vlo(), hi = ref.vhi();
      _mm_store_si128(reinterpret_cast<__m128i*>(k), m.bins(_mm_add_ps(lo, hi)));
      for (int a = 0; a < 3; ++a) {
        acc.box[a][k[a]].extend(lo, hi);
        ++acc.count[a][k[a]];
      }
    }
  }

  Bins bin_range(const BinMapper& m, int nb, size_t begin, size_t end) const {
    if (end - begin < kParallelBinThreshold) {
      Bins acc(nb);
      bin_into(acc, m, begin, end);
      return acc;
    }
    return tbb::parallel_reduce(
        tbb::blocked_range<size_t>(begin, end, 16 * 1024), Bins(nb),
        [&](const tbb::blocked_range<size_t>& r, Bins acc) {
          bin_into(acc, m, r.begin(), r.end());
          return acc;
        },
        [](Bins x, const Bins& y) { x.merge(y); return x; });
  }

  // Bounds and centroid bounds of refs[begin, end).
  void bound(Range& r) const {
    Box4 box = Box4::empty(), cbox = Box4::empty();
    for (uint32_t i = r.begin; i < r.end; ++i) {
      const __m128 lo = refs[i].vlo(), hi = refs[i].vhi();
      box.extend(lo, hi);
      cbox.extend(_mm_add_ps(lo, hi));
    }
    r.box = box.bounds();
    r.cbox = cbox.bounds();
  }

  // Splits r at mid into l and rr (refs already ordered), computing both sides' bounds.
  void halves(const Range& r, uint32_t mid, Range& l, Range& rr) const {
    l.begin = r.begin;
    l.end = mid;
    rr.begin = mid;
    rr.end = r.end;
    l.depth = rr.depth = r.depth + 1;
    bound(l);
    bound(rr);
  }

  // Decides whether r becomes a leaf (false) or is split (true, refs partitioned into l and rr).
  bool split(const Range& r, Range& l, Range& rr) {
    const uint32_t n = r.size();
    if (n == 1) return false;
    const uint32_t max_leaf = leaf_limit();
    // One packet's worth of primitives: a leaf is one 4-wide test; no split can be cheaper than that.
    if (n <= max_leaf && n <= uint32_t(kWidth)) return false;

    const int axis = r.cbox.max_extent();
    const Vec3 ext = r.cbox.diagonal();
    if (!(ext[axis] > 0.f)) {
      // All centroids coincide: no split separates them; a small set becomes a leaf, a large one is halved.
      if (n <= max_leaf) return false;
      halves(r, r.begin + n / 2, l, rr);
      return true;
    }
    if (opt.split == SplitMethod::kMedian || r.depth >= kForceMedianDepth) {
      if (n <= max_leaf) return false;
      const uint32_t mid = r.begin + n / 2;
      std::nth_element(refs.begin() + r.begin, refs.begin() + mid, refs.begin() + r.end,
                       [axis](const BuildRef& x, const BuildRef& y) {
                         return x.lo[axis] + x.hi[axis] < y.lo[axis] + y.hi[axis];
                       });
      halves(r, mid, l, rr);
      return true;
    }

    // No more bins than references: small ranges are the most numerous, and their cost is mostly per bin.
    const int nb = std::clamp(std::min(opt.bins, int(n)), 2, kMaxBins);
    const BinMapper m(r.cbox, nb);
    const Bins bins = bin_range(m, nb, r.begin, r.end);

    // Cost of a side: area times packets, so that a leaf's partly filled packet counts as a whole test.
    float best_cost = kInfinity;
    int best_axis = -1, best_split = 0;
    Box4 best_lbox = Box4::empty(), best_rbox = Box4::empty();
    for (int a = 0; a < 3; ++a) {
      if (!(ext[a] > 0.f)) continue;
      std::array<float, kMaxBins> right_cost;
      std::array<Box4, kMaxBins> right_box;
      Box4 acc = Box4::empty();
      uint32_t cnt = 0;
      for (int i = nb - 1; i > 0; --i) {
        acc.extend(bins.box[a][i]);
        cnt += bins.count[a][i];
        right_cost[i] = cnt ? float(packets_for(cnt)) * acc.area() : 0.f;
        right_box[i] = acc;
      }
      acc = Box4::empty();
      cnt = 0;
      for (int i = 0; i < nb - 1; ++i) {
        acc.extend(bins.box[a][i]);
        cnt += bins.count[a][i];
        if (cnt == 0 || cnt == n) continue;
        const float cost = float(packets_for(cnt)) * acc.area() + right_cost[i + 1];
        if (cost < best_cost) {
          best_cost = cost;
          best_axis = a;
          best_split = i + 1;
          best_lbox = acc;
          best_rbox = right_box[i + 1];
        }
      }
    }
    const float area = r.box.surface_area();
    const float split_cost = kTraversalCost + kPacketCost * (area > 0.f ? best_cost / area : 0.f);
    const float leaf_cost = kPacketCost * float(packets_for(n));
    if (best_axis < 0) {
      if (n <= max_leaf) return false;
      halves(r, r.begin + n / 2, l, rr);
      return true;
    }
    if (n <= max_leaf && leaf_cost <= split_cost) return false;

    // Partition by bin, gathering both sides' centroid bounds on the way; the boxes come from the bins.
    Box4 lc = Box4::empty(), rc = Box4::empty();
    BuildRef* lo = refs.data() + r.begin;
    BuildRef* hi = refs.data() + r.end;
    for (;;) {
      __m128 c;
      while (lo < hi && m.bin(c = lo->c2(), best_axis) < best_split) {
        lc.extend(c);
        ++lo;
      }
      while (lo < hi && m.bin(c = (hi - 1)->c2(), best_axis) >= best_split) {
        rc.extend(c);
        --hi;
      }
      if (lo >= hi) break;
      std::swap(*lo, *(hi - 1));
      lc.extend(lo->c2());
      rc.extend((hi - 1)->c2());
      ++lo;
      --hi;
    }
    const uint32_t mid = uint32_t(lo - refs.data());
    if (mid == r.begin || mid == r.end) {  // unreachable with exact binning; stay safe
      halves(r, r.begin + n / 2, l, rr);
      return true;
    }
    l = Range{r.begin, mid, best_lbox.bounds(), lc.bounds(), r.depth + 1};
    rr = Range{mid, r.end, best_rbox.bounds(), rc.bounds(), r.depth + 1};
    return true;
  }

  // Writes refs[r] as packets (triangles first, then spheres) and returns the leaf's child reference.
  uint32_t emit_leaf(const Range& r) {
    uint32_t nt = 0;
    const uint32_t ntri = bvh.num_triangles_;
    for (uint32_t i = r.begin; i < r.end; ++i) nt += refs[i].id < ntri;
    const uint32_t ns = r.size() - nt;
    // Triangles before spheres inside the leaf, keeping their order otherwise.
    if (nt > 0 && ns > 0)
      std::stable_partition(refs.begin() + r.begin, refs.begin() + r.end,
                            [ntri](const BuildRef& x) { return x.id < ntri; });
    const uint32_t count = packets_for(nt) + packets_for(ns);
    const uint32_t first = next_packet.fetch_add(count, std::memory_order_relaxed);
    Packet* out = bvh.packets_.data() + first;
    uint32_t i = r.begin;
    for (uint32_t p = 0; p < count; ++p) {
      Packet& pk = out[p];
      pk = Packet{};
      const bool tri = i < r.end && refs[i].id < ntri;
      for (int lane = 0; lane < kWidth; ++lane) {
        if (i < r.end && (refs[i].id < ntri) == tri) {
          const uint32_t id = refs[i++].id;
          pk.id[lane] = id;
          if (tri) {
            const Triangle& t = triangles[id];
            const Vec3* v[3] = {&t.p0, &t.p1, &t.p2};
            for (int k = 0; k < 3; ++k)
              for (int a = 0; a < 3; ++a) pk.v[k][a][lane] = (*v[k])[a];
          } else {
            const Sphere& s = spheres[id - ntri];
            for (int a = 0; a < 3; ++a) pk.v[0][a][lane] = s.center[a];
            pk.v[1][0][lane] = s.radius;
          }
        } else {
          pk.id[lane] = kNoPrim;
        }
      }
    }
    out[count - 1].id[0] |= kLastPacket;
    return kLeafBit | first;
  }

  struct Child {
    Range r;
    Range l, rr;  // halves when split
    enum State : uint8_t { kUnknown, kLeaf, kSplit } state = kUnknown;
    float area() const { return r.box.surface_area(); }
    void decide(Builder& b) { state = b.split(r, l, rr) ? kSplit : kLeaf; }
  };

  // Builds the node at index idx over a range already split into a and b: opens the child with the largest area
  // until there are four children or none can be split, then recurses into the interior children.
  void build_node(uint32_t idx, const Range& a, const Range& b) {
    std::array<Child, kWidth> c;
    c[0].r = a;
    c[1].r = b;
    int nc = 2;
    if (a.size() > kParallelTaskThreshold && b.size() > kParallelTaskThreshold) {
      // Both halves will be opened: split them side by side (near the root, partitions are serial otherwise).
      tbb::parallel_invoke([&] { c[0].decide(*this); }, [&] { c[1].decide(*this); });
    }
    while (nc < kWidth) {
      int best = -1;
      float best_area = -1.f;
      for (int k = 0; k < nc; ++k) {
        if (c[k].state == Child::kLeaf) continue;
        const float ar = c[k].area();
        if (ar > best_area) { best_area = ar; best = k; }
      }
      if (best < 0) break;
      Child& ch = c[best];
      if (ch.state == Child::kUnknown) {
        ch.decide(*this);
        if (ch.state == Child::kLeaf) continue;
      }
      const Range l = ch.l, rr = ch.rr;
      c[best] = Child{};
      c[best].r = l;
      c[nc] = Child{};
      c[nc].r = rr;
      ++nc;
    }
    for (int k = 0; k < nc; ++k)
      if (c[k].state == Child::kUnknown) c[k].decide(*this);

    int interior = 0;
    for (int k = 0; k < nc; ++k) interior += c[k].state == Child::kSplit;
    const uint32_t base = interior ? next_node.fetch_add(uint32_t(interior), std::memory_order_relaxed) : 0;

    Node& node = bvh.nodes_[idx];
    uint32_t next = base;
    for (int k = 0; k < kWidth; ++k) {
      if (k < nc) {
        const Bounds3& bx = c[k].r.box;
        for (int ax = 0; ax < 3; ++ax) {
          node.box[2 * ax][k] = bx.lo[ax];
          node.box[2 * ax + 1][k] = bx.hi[ax];
        }
        node.child[k] = c[k].state == Child::kLeaf ? emit_leaf(c[k].r) : next++;
      } else {
        for (int ax = 0; ax < 3; ++ax) {
          node.box[2 * ax][k] = kInfinity;
          node.box[2 * ax + 1][k] = -kInfinity;
        }
        node.child[k] = 0;
      }
      node.pad[k] = 0;
    }

    tbb::task_group tg;
    bool spawned = false;
    next = base;
    for (int k = 0; k < nc; ++k) {
      if (c[k].state != Child::kSplit) continue;
      const uint32_t ci = next++;
      const Child& ch = c[k];
      if (ch.r.size() > kParallelTaskThreshold) {
        tg.run([this, ci, l = ch.l, rr = ch.rr] { build_node(ci, l, rr); });
        spawned = true;
      } else {
        build_node(ci, ch.l, ch.rr);
      }
    }
    if (spawned) tg.wait();
  }
};

Bvh Bvh::build(std::span<const Triangle> triangles, std::span<const Sphere> spheres, const BvhOptions& options) {
  Bvh bvh;
  if (triangles.size() + spheres.size() >= (size_t(1) << 31)) throw std::length_error("Bvh: too many primitives");
  bvh.num_triangles_ = uint32_t(triangles.size());
  bvh.num_spheres_ = uint32_t(spheres.size());

  // Degenerate triangles and empty spheres can never be hit; leaving them out keeps boxes tight. References are
  // made in parallel with an id of kNoPrim for the ones left out (compacted afterwards, in order, if any), and
  // the root's bounds are reduced on the way.
  const size_t total = triangles.size() + spheres.size();
  RefVector refs(total);
  struct Acc {
    Box4 box = Box4::empty(), cbox = Box4::empty();
    size_t dropped = 0;
  };
  const Acc acc = tbb::parallel_reduce(
      tbb::blocked_range<size_t>(0, total, 16 * 1024), Acc{},
      [&](const tbb::blocked_range<size_t>& range, Acc a) {
        for (size_t i = range.begin(); i != range.end(); ++i) {
          BuildRef& r = refs[i];
          Bounds3 box;
          bool ok;
          if (i < triangles.size()) {
            const Triangle& t = triangles[i];
            ok = !is_degenerate(t);
            box.extend(t.p0);
            box.extend(t.p1);
            box.extend(t.p2);
          } else {
            const Sphere& s = spheres[i - triangles.size()];
            ok = s.radius > 0.f && std::isfinite(s.radius) && is_finite(s.center);
            box = Bounds3{s.center - Vec3(s.radius), s.center + Vec3(s.radius)};
          }
          for (int k = 0; k < 3; ++k) {
            r.lo[k] = box.lo[k];
            r.hi[k] = box.hi[k];
          }
          r.pad = 0;
          if (!ok) {
            r.id = kNoPrim;
            ++a.dropped;
            continue;
          }
          r.id = uint32_t(i);
          const __m128 lo = r.vlo(), hi = r.vhi();
          a.box.extend(lo, hi);
          a.cbox.extend(_mm_add_ps(lo, hi));
        }
        return a;
      },
      [](Acc x, const Acc& y) {
        x.box.extend(y.box);
        x.cbox.extend(y.cbox);
        x.dropped += y.dropped;
        return x;
      });
  if (acc.dropped > 0) {
    size_t w = 0;
    for (size_t i = 0; i < total; ++i)
      if (refs[i].id != kNoPrim) refs[w++] = refs[i];
    refs.resize(w);
  }
  if (refs.empty()) return bvh;
  Range root;
  root.begin = 0;
  root.end = uint32_t(refs.size());
  root.box = acc.box.bounds();
  root.cbox = acc.cbox.bounds();
  bvh.bounds_ = root.box;

  // Upper bounds: every node but the root has at least two children and every leaf at least one primitive, so
  // nodes <= leaves <= references; a leaf never has more packets than primitives. The storage is not initialised,
  // so the unused tail costs address space only.
  const size_t n = refs.size();
  bvh.nodes_.resize(n + 1);
  bvh.packets_.resize(n);

  Builder b(options, refs, triangles, spheres, bvh);
  const uint32_t root_idx = b.next_node.fetch_add(1);
  Range l, r;
  if (b.split(root, l, r)) {
    b.build_node(root_idx, l, r);
  } else {
    // The whole scene is one leaf: a root with a single child.
    Node& node = bvh.nodes_[root_idx];
    for (int k = 0; k < kWidth; ++k) {
      for (int ax = 0; ax < 3; ++ax) {
        node.box[2 * ax][k] = k == 0 ? root.box.lo[ax] : kInfinity;
        node.box[2 * ax + 1][k] = k == 0 ? root.box.hi[ax] : -kInfinity;
      }
      node.child[k] = 0;
      node.pad[k] = 0;
    }
    node.child[0] = b.emit_leaf(root);
  }
  bvh.nodes_.resize(b.next_node.load());
  bvh.packets_.resize(b.next_packet.load());
  return bvh;
}

// ------------------------------------------------------------------------------------------------------------
// Traversal.

namespace {

// Per-ray constants of the 4-wide slab test. The arithmetic per lane is exactly slab_test()'s (bounds.h): near
// and far planes chosen by the direction's sign, (plane - o) * inv_d, the far distance scaled by 1 + 2*gamma(3),
// and max/min that keep the running value when the new distance is NaN (MAXPS/MINPS return their second operand
// on unordered inputs).
struct SimdBoxRay {
  __m128 o[3], inv_d[3];
  int near_row[3], far_row[3];  // rows of Node::box
  explicit SimdBoxRay(const BoxRay& br) {
    for (int a = 0; a < 3; ++a) {
      o[a] = _mm_set1_ps(br.o[a]);
      inv_d[a] = _mm_set1_ps(br.inv_d[a]);
      near_row[a] = 2 * a + (br.neg[a] ? 1 : 0);
      far_row[a] = 2 * a + (br.neg[a] ? 0 : 1);
    }
  }
};

constexpr float kFarScale = 1.f + 2.f * gamma(3);

// Slab test of the four child boxes against (0, tmax); returns the mask of boxes entered and their entry distances.
template <class NodeT>
inline int slab_test4(const NodeT& n, const SimdBoxRay& r, __m128 tmax, __m128* t_entry) {
  const __m128 scale = _mm_set1_ps(kFarScale);
  __m128 t0 = _mm_setzero_ps(), t1 = tmax;
  for (int a = 0; a < 3; ++a) {
    const __m128 tn = _mm_mul_ps(_mm_sub_ps(_mm_load_ps(n.box[r.near_row[a]]), r.o[a]), r.inv_d[a]);
    const __m128 tf =
        _mm_mul_ps(_mm_mul_ps(_mm_sub_ps(_mm_load_ps(n.box[r.far_row[a]]), r.o[a]), r.inv_d[a]), scale);
    t0 = _mm_max_ps(tn, t0);  // tn > t0 ? tn : t0
    t1 = _mm_min_ps(tf, t1);  // tf < t1 ? tf : t1
  }
  *t_entry = t0;
  return _mm_movemask_ps(_mm_cmple_ps(t0, t1));
}

// Per-ray constants of the 4-wide watertight test (the same as WatertightRay, broadcast).
struct SimdTriRay {
  const WatertightRay& wr;
  __m128 ox, oy, oz, sx, sy, sz;
  explicit SimdTriRay(const WatertightRay& w)
      : wr(w),
        ox(_mm_set1_ps(w.o[w.kx])),
        oy(_mm_set1_ps(w.o[w.ky])),
        oz(_mm_set1_ps(w.o[w.kz])),
        sx(_mm_set1_ps(w.sx)),
        sy(_mm_set1_ps(w.sy)),
        sz(_mm_set1_ps(w.sz)) {}
};

// Results of four triangle tests: lanes that hit in (0, tmax), with t and the barycentrics of p1 and p2.
struct Lanes4 {
  alignas(16) float t[4];
  alignas(16) float b1[4];
  alignas(16) float b2[4];
};

// The watertight test (triangle.h) on the four triangles of a packet, lane by lane with the same operations in
// the same order, so t and the barycentrics are bitwise those of intersect_triangle(). Lanes whose float edge
// functions are zero or whose determinant is not finite go to the same double-precision fallback.
// `valid` is the mask of used lanes. Returns the mask of lanes that hit; fills `out` for them when given.
inline int intersect_triangles4(const float (&v)[3][3][4], int valid, const SimdTriRay& r, float tmax,
                                Lanes4* out) {
  const WatertightRay& w = r.wr;
  const __m128 az = _mm_sub_ps(_mm_load_ps(v[0][w.kz]), r.oz);
  const __m128 bz = _mm_sub_ps(_mm_load_ps(v[1][w.kz]), r.oz);
  const __m128 cz = _mm_sub_ps(_mm_load_ps(v[2][w.kz]), r.oz);
  const __m128 ax = _mm_sub_ps(_mm_sub_ps(_mm_load_ps(v[0][w.kx]), r.ox), _mm_mul_ps(r.sx, az));
  const __m128 ay = _mm_sub_ps(_mm_sub_ps(_mm_load_ps(v[0][w.ky]), r.oy), _mm_mul_ps(r.sy, az));
  const __m128 bx = _mm_sub_ps(_mm_sub_ps(_mm_load_ps(v[1][w.kx]), r.ox), _mm_mul_ps(r.sx, bz));
  const __m128 by = _mm_sub_ps(_mm_sub_ps(_mm_load_ps(v[1][w.ky]), r.oy), _mm_mul_ps(r.sy, bz));
  const __m128 cx = _mm_sub_ps(_mm_sub_ps(_mm_load_ps(v[2][w.kx]), r.ox), _mm_mul_ps(r.sx, cz));
  const __m128 cy = _mm_sub_ps(_mm_sub_ps(_mm_load_ps(v[2][w.ky]), r.oy), _mm_mul_ps(r.sy, cz));

  const __m128 e0 = _mm_sub_ps(_mm_mul_ps(bx, cy), _mm_mul_ps(by, cx));
  const __m128 e1 = _mm_sub_ps(_mm_mul_ps(cx, ay), _mm_mul_ps(cy, ax));
  const __m128 e2 = _mm_sub_ps(_mm_mul_ps(ax, by), _mm_mul_ps(ay, bx));
  const __m128 det = _mm_add_ps(_mm_add_ps(e0, e1), e2);

  const __m128 zero = _mm_setzero_ps();
  const __m128 abs_mask = _mm_castsi128_ps(_mm_set1_epi32(0x7fffffff));
  const __m128 finite = _mm_cmple_ps(_mm_and_ps(det, abs_mask), _mm_set1_ps(std::numeric_limits<float>::max()));
  const __m128 any_zero = _mm_or_ps(_mm_or_ps(_mm_cmpeq_ps(e0, zero), _mm_cmpeq_ps(e1, zero)), _mm_cmpeq_ps(e2, zero));
  const int fallback = _mm_movemask_ps(any_zero) | (_mm_movemask_ps(finite) ^ 0xf);
  const int fb = fallback & valid;

  const __m128 neg = _mm_or_ps(_mm_or_ps(_mm_cmplt_ps(e0, zero), _mm_cmplt_ps(e1, zero)), _mm_cmplt_ps(e2, zero));
  const __m128 pos = _mm_or_ps(_mm_or_ps(_mm_cmpgt_ps(e0, zero), _mm_cmpgt_ps(e1, zero)), _mm_cmpgt_ps(e2, zero));
  int hit = valid & ~fallback & ~_mm_movemask_ps(_mm_and_ps(neg, pos));
  if (!hit && !fb) return 0;

  const __m128 inv_det = _mm_div_ps(_mm_set1_ps(1.f), det);
  const __m128 szaz = _mm_mul_ps(r.sz, az), szbz = _mm_mul_ps(r.sz, bz), szcz = _mm_mul_ps(r.sz, cz);
  const __m128 t = _mm_mul_ps(
      _mm_add_ps(_mm_add_ps(_mm_mul_ps(e0, szaz), _mm_mul_ps(e1, szbz)), _mm_mul_ps(e2, szcz)), inv_det);
  hit &= _mm_movemask_ps(_mm_and_ps(_mm_cmpgt_ps(t, zero), _mm_cmplt_ps(t, _mm_set1_ps(tmax))));
  if (out && hit) {
    _mm_store_ps(out->t, t);
    _mm_store_ps(out->b1, _mm_mul_ps(e1, inv_det));
    _mm_store_ps(out->b2, _mm_mul_ps(e2, inv_det));
  }
  if (fb) {
    alignas(16) float s[9][4];
    _mm_store_ps(s[0], ax); _mm_store_ps(s[1], ay); _mm_store_ps(s[2], az);
    _mm_store_ps(s[3], bx); _mm_store_ps(s[4], by); _mm_store_ps(s[5], bz);
    _mm_store_ps(s[6], cx); _mm_store_ps(s[7], cy); _mm_store_ps(s[8], cz);
    for (int m = fb; m; m &= m - 1) {
      const int k = std::countr_zero(unsigned(m));
      const detail::Sheared sh{s[0][k], s[1][k], s[2][k], s[3][k], s[4][k], s[5][k], s[6][k], s[7][k], s[8][k]};
      if (const auto h = detail::intersect_sheared_double(sh, w.sz, tmax)) {
        hit |= 1 << k;
        if (!out) return hit;
        out->t[k] = h->t;
        out->b1[k] = h->b1;
        out->b2[k] = h->b2;
      }
    }
  }
  return hit;
}

inline int valid_lanes(const uint32_t (&id)[4]) {
  const __m128i ids = _mm_load_si128(reinterpret_cast<const __m128i*>(id));
  return _mm_movemask_ps(_mm_castsi128_ps(_mm_cmpeq_epi32(ids, _mm_set1_epi32(-1)))) ^ 0xf;
}

// Asks for the cache lines a child reference will touch first: a node's two lines or a leaf's first packet.
template <class NodeT, class PacketT>
inline void prefetch_child(uint32_t ref, const NodeT* nodes, const PacketT* packets, uint32_t leaf_bit) {
  const char* p = (ref & leaf_bit) ? reinterpret_cast<const char*>(packets + (ref & ~leaf_bit))
                                   : reinterpret_cast<const char*>(nodes + ref);
  _mm_prefetch(p, _MM_HINT_T0);
  _mm_prefetch(p + 64, _MM_HINT_T0);
  if (ref & leaf_bit) _mm_prefetch(p + 128, _MM_HINT_T0);
}

struct StackEntry {
  uint32_t ref;
  float t;  // entry distance when pushed
};

constexpr int kStackSize = 3 * Bvh::kMaxDepth + 4;

}  // namespace

std::optional<Hit> Bvh::intersect(const Ray& ray) const {
  if (nodes_.empty() || !ray.valid()) return std::nullopt;
  const BoxRay br(ray);
  const SimdBoxRay sr(br);
  const WatertightRay wr(ray);
  const SimdTriRay tr(wr);
  float tmax = ray.tmax;
  Hit best{};
  bool found = false;

  StackEntry stack[kStackSize];
  int sp = 0;
  uint32_t ref = 0;
  for (;;) {
    while (!(ref & kLeafBit)) {
      const Node& n = nodes_[ref];
      __m128 tn;
      const int mask = slab_test4(n, sr, _mm_set1_ps(tmax), &tn);
      if (mask == 0) goto pop;
      const int c0 = std::countr_zero(unsigned(mask));
      const int rest = mask & (mask - 1);
      if (rest == 0) {
        ref = n.child[c0];
        continue;
      }
      alignas(16) float t[4];
      _mm_store_ps(t, tn);
      const int c1 = std::countr_zero(unsigned(rest));
      if ((rest & (rest - 1)) == 0) {
        // Two boxes: visit the nearer first.
        const bool swap = t[c1] < t[c0];
        const int near = swap ? c1 : c0, far = swap ? c0 : c1;
        stack[sp++] = {n.child[far], t[far]};
        prefetch_child(n.child[far], nodes_.data(), packets_.data(), kLeafBit);
        ref = n.child[near];
        continue;
      }
      // Three or four: sort by entry distance, farthest pushed first, nearest visited now.
      StackEntry e[4];
      int ne = 0;
      for (int m = mask; m; m &= m - 1) {
        const int k = std::countr_zero(unsigned(m));
        StackEntry x{n.child[k], t[k]};
        int j = ne++;
        while (j > 0 && e[j - 1].t < x.t) {
          e[j] = e[j - 1];
          --j;
        }
        e[j] = x;
      }
      for (int k = 0; k < ne - 1; ++k) {
        stack[sp++] = e[k];
        prefetch_child(e[k].ref, nodes_.data(), packets_.data(), kLeafBit);
      }
      ref = e[ne - 1].ref;
    }
    // Leaf.
    for (const Packet* pk = &packets_[ref & ~kLeafBit];; ++pk) {
      const uint32_t id0 = pk->id[0] & ~kLastPacket;
      const int valid = valid_lanes(pk->id);
      if (id0 < num_triangles_) {
        Lanes4 lanes;
        for (int m = intersect_triangles4(pk->v, valid, tr, tmax, &lanes); m; m &= m - 1) {
          const int k = std::countr_zero(unsigned(m));
          if (lanes.t[k] < tmax) {  // lanes in order, as a sequential loop would accept them
            tmax = lanes.t[k];
            best = Hit{lanes.t[k], lanes.b1[k], lanes.b2[k], k == 0 ? id0 : pk->id[k]};
            found = true;
          }
        }
      } else {
        for (int m = valid; m; m &= m - 1) {
          const int k = std::countr_zero(unsigned(m));
          const Sphere s{Vec3(pk->v[0][0][k], pk->v[0][1][k], pk->v[0][2][k]), pk->v[1][0][k]};
          if (auto th = intersect_sphere(s, ray, tmax)) {
            tmax = *th;
            best = Hit{*th, 0.f, 0.f, k == 0 ? id0 : pk->id[k]};
            found = true;
          }
        }
      }
      if (pk->id[0] & kLastPacket) break;
    }
  pop:
    for (;;) {
      if (sp == 0) {
        if (!found) return std::nullopt;
        return best;
      }
      const StackEntry& e = stack[--sp];
      if (e.t <= tmax) {  // the slab test against the shortened ray, given it passed against the longer one
        ref = e.ref;
        break;
      }
    }
  }
}

bool Bvh::occluded(const Ray& ray) const {
  if (nodes_.empty() || !ray.valid()) return false;
  const BoxRay br(ray);
  const SimdBoxRay sr(br);
  const WatertightRay wr(ray);
  const SimdTriRay tr(wr);
  const float tmax = ray.tmax;
  const __m128 tmax4 = _mm_set1_ps(tmax);

  uint32_t stack[kStackSize];
  int sp = 0;
  uint32_t ref = 0;
  for (;;) {
    while (!(ref & kLeafBit)) {
      const Node& n = nodes_[ref];
      __m128 tn;
      int mask = slab_test4(n, sr, tmax4, &tn);
      if (mask == 0) goto pop;
      ref = n.child[std::countr_zero(unsigned(mask))];
      for (mask &= mask - 1; mask; mask &= mask - 1) {
        const uint32_t c = n.child[std::countr_zero(unsigned(mask))];
        stack[sp++] = c;
        prefetch_child(c, nodes_.data(), packets_.data(), kLeafBit);
      }
    }
    for (const Packet* pk = &packets_[ref & ~kLeafBit];; ++pk) {
      const int valid = valid_lanes(pk->id);
      if ((pk->id[0] & ~kLastPacket) < num_triangles_) {
        if (intersect_triangles4(pk->v, valid, tr, tmax, nullptr)) return true;
      } else {
        for (int m = valid; m; m &= m - 1) {
          const int k = std::countr_zero(unsigned(m));
          const Sphere s{Vec3(pk->v[0][0][k], pk->v[0][1][k], pk->v[0][2][k]), pk->v[1][0][k]};
          if (intersect_sphere(s, ray, tmax)) return true;
        }
      }
      if (pk->id[0] & kLastPacket) break;
    }
  pop:
    if (sp == 0) return false;
    ref = stack[--sp];
  }
}

BvhStats Bvh::stats() const {
  BvhStats s;
  if (nodes_.empty()) return s;
  const double root_area = bounds_.surface_area();
  struct Item {
    uint32_t ref;
    int depth;
    double rel;  // area of the node's box relative to the root's
  };
  std::vector<Item> todo{{0, 0, 1.0}};
  double cost = 0.0;
  while (!todo.empty()) {
    const Item it = todo.back();
    todo.pop_back();
    ++s.nodes;
    if (it.ref & kLeafBit) {
      ++s.leaves;
      s.max_depth = std::max(s.max_depth, it.depth);
      size_t prims = 0;
      for (const Packet* pk = &packets_[it.ref & ~kLeafBit];; ++pk) {
        prims += size_t(std::popcount(unsigned(valid_lanes(pk->id))));
        if (pk->id[0] & kLastPacket) break;
      }
      cost += it.rel * double(prims);
      continue;
    }
    cost += it.rel;
    const Node& n = nodes_[it.ref];
    for (int k = 0; k < kWidth; ++k) {
      const Bounds3 b{Vec3(n.box[0][k], n.box[2][k], n.box[4][k]), Vec3(n.box[1][k], n.box[3][k], n.box[5][k])};
      if (b.empty()) continue;
      const double rel = root_area > 0 ? b.surface_area() / root_area : 1.0;
      todo.push_back({n.child[k], it.depth + 1, rel});
    }
  }
  s.sah_cost = cost;
  return s;
}

}  // namespace tessera
