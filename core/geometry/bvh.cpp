#include "core/geometry/bvh.h"

#include "core/geometry/kernels/bvh_kernels.h"

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
#include <string>
#include <type_traits>

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
constexpr size_t kParallelPartition = 256 * 1024;    // refs; below this a partition runs on one thread
constexpr int kForceMedianDepth = 40;  // binary split depth past which splits use the object median (bounded depth)
using bvh_layout::kLastPacket;
using bvh_layout::kLeafBit;
using bvh_layout::kNoPrim;
constexpr int kNodeWidth = bvh_layout::kNodeWidth;
constexpr int kPacketWidth = bvh_layout::kPacketWidth;

// SAH constants of the binary build, in units of one leaf packet (eight primitives) test: they decide between a
// leaf and a split for small ranges, where a split must shrink the children's boxes to half the area to pay.
constexpr float kTraversalCost = 0.5f;
constexpr float kPacketCost = 1.f;

inline uint32_t packets_for(uint32_t prims) { return (prims + kPacketWidth - 1) / kPacketWidth; }

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
  // 2 (dx dy + dy dz + dz dx), in registers; 0 for an empty box.
  float area() const {
    const __m128 d = _mm_max_ps(_mm_sub_ps(hi, lo), _mm_setzero_ps());
    const __m128 p = _mm_mul_ps(d, _mm_shuffle_ps(d, d, _MM_SHUFFLE(3, 0, 2, 1)));  // dx dy, dy dz, dz dx
    const __m128 sum = _mm_add_ss(_mm_add_ss(p, _mm_shuffle_ps(p, p, _MM_SHUFFLE(1, 1, 1, 1))), _mm_movehl_ps(p, p));
    return 2.f * _mm_cvtss_f32(sum);
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
};

// Whether a reference's bin on Axis (by a BinMapper) is below `split`, 1 <= split <= nb - 1, from that axis alone:
// max((c - lo) * scale, 0) < split, the same IEEE operations as BinMapper::bins() on that lane (a NaN also becomes
// 0); clamping to nb - 1 and truncating cannot change the comparison.
template <int Axis>
struct LeftOf {
  __m128 lo, scale, split;
  LeftOf(const BinMapper& m, int s) {
    alignas(16) float l[4], sc[4];
    _mm_store_ps(l, m.lo);
    _mm_store_ps(sc, m.scale);
    lo = _mm_set_ss(l[Axis]);
    scale = _mm_set_ss(sc[Axis]);
    split = _mm_set_ss(float(s));
  }
  bool operator()(const BuildRef& x) const {
    const __m128 c = _mm_add_ss(_mm_load_ss(&x.lo[Axis]), _mm_load_ss(&x.hi[Axis]));
    const __m128 f = _mm_max_ss(_mm_mul_ss(_mm_sub_ss(c, lo), scale), _mm_setzero_ps());
    return _mm_comilt_ss(f, split);
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

  Builder(const BvhOptions& o, RefVector& r, std::span<const Triangle> t, std::span<const Sphere> s, Bvh& b)
      : opt(o), refs(r), triangles(t), spheres(s), bvh(b) {}

  uint32_t leaf_limit() const { return uint32_t(std::clamp(opt.max_leaf_prims, 1, 255)); }

  // Bin indices of refs [first, first + n) on the three axes, into bin[i][0..2].
  static void bin_indices(const BinMapper& m, const BuildRef* first, size_t n, int32_t (*bin)[4]) {
    for (size_t i = 0; i < n; ++i) _mm_store_si128(reinterpret_cast<__m128i*>(bin[i]), m.bins(first[i].c2()));
  }

  // Adds refs [first, first + n), whose bin indices are bin[0..n), to acc.
  static void bin_refs(Bins& acc, const BuildRef* first, size_t n, const int32_t (*bin)[4]) {
    for (size_t i = 0; i < n; ++i) {
      const __m128 lo = first[i].vlo(), hi = first[i].vhi();
      for (int a = 0; a < 3; ++a) {
        const int k = bin[i][a];
        acc.box[a][k].extend(lo, hi);
        ++acc.count[a][k];
      }
    }
  }

  // Bins refs[begin, end) into acc, kBinBlock references at a time: their bin indices first, then the updates. With
  // the indices known ahead, the processor knows which updates touch the same bin (neighbours often do) before it
  // runs them; computing each index just before its update made binning about 1.3-1.8x slower.
  static constexpr size_t kBinBlock = 32;
  void bin_into(Bins& acc, const BinMapper& m, size_t begin, size_t end) const {
    alignas(16) int32_t bin[kBinBlock][4];
    for (size_t i = begin; i < end; i += kBinBlock) {
      const size_t n = std::min(kBinBlock, end - i);
      bin_indices(m, refs.data() + i, n, bin);
      bin_refs(acc, refs.data() + i, n, bin);
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

  // Moves the references of [first, last) whose bin on Axis is below `split` to the front and returns the first of
  // the others. Blocks of kBlock references are classified without branches, recording the misplaced ones, which
  // are then swapped in pairs (as in Edelkamp and Weiss's BlockQuicksort): the classification's outcome is random
  // per reference, so branching on it would mispredict about every other time.
  template <int Axis>
  static BuildRef* partition(const BinMapper& m, int split, BuildRef* first, BuildRef* last) {
    constexpr int kBlock = 64;
    const LeftOf<Axis> left_of(m, split);
    uint8_t off_l[kBlock], off_r[kBlock];
    int num_l = 0, num_r = 0, start_l = 0, start_r = 0;
    while (last - first > 2 * kBlock) {
      if (num_l == 0) {
        start_l = 0;
        for (int i = 0; i < kBlock; ++i) {
          off_l[num_l] = uint8_t(i);
          num_l += !left_of(first[i]);
        }
      }
      if (num_r == 0) {
        start_r = 0;
        for (int i = 0; i < kBlock; ++i) {
          off_r[num_r] = uint8_t(i);
          num_r += left_of(*(last - 1 - i));
        }
      }
      const int num = std::min(num_l, num_r);
      for (int j = 0; j < num; ++j) std::swap(first[off_l[start_l + j]], *(last - 1 - off_r[start_r + j]));
      num_l -= num;
      num_r -= num;
      start_l += num;
      start_r += num;
      if (num_l == 0) first += kBlock;
      if (num_r == 0) last -= kBlock;
    }
    // Left: at most one classified block with misplaced references, and an unclassified middle. The block's
    // misplaced references are gathered at its inner end (offsets increase away from the outer end, so each swap
    // target holds a placed reference or the misplaced one itself); the rest is partitioned with branches.
    if (num_l > 0) {
      BuildRef* block_end = first + kBlock;
      for (int j = num_l - 1; j >= 0; --j) std::swap(first[off_l[start_l + j]], *--block_end);
      return finish_partition(left_of, block_end, last);
    }
    if (num_r > 0) {
      BuildRef* block_begin = last - kBlock;
      for (int j = num_r - 1; j >= 0; --j) std::swap(*(last - 1 - off_r[start_r + j]), *block_begin++);
      return finish_partition(left_of, first, block_begin);
    }
    return finish_partition(left_of, first, last);
  }

  // partition() for any size, with the centroid bounds of both sides (lcb, rcb): ranges of kParallelPartition
  // references or more are cut into fixed chunks partitioned (and bounded, while in cache) in parallel, then the
  // right-side references left of the final cut are swapped with the left-side ones right of it, in a fixed pairing.
  // The result depends only on the input, never on the threads.
  template <int Axis>
  static BuildRef* partition_any(const BinMapper& m, int split, BuildRef* first, BuildRef* last, Box4& lcb,
                                 Box4& rcb) {
    constexpr size_t kChunk = 32 * 1024;
    const size_t n = size_t(last - first);
    if (n < kParallelPartition) {
      BuildRef* const cut = partition<Axis>(m, split, first, last);
      lcb = centroid_bounds(first, cut);
      rcb = centroid_bounds(cut, last);
      return cut;
    }
    const size_t chunks = (n + kChunk - 1) / kChunk;
    std::vector<size_t> cuts(chunks);  // left-side count of each chunk
    std::vector<Box4> chunk_lcb(chunks), chunk_rcb(chunks);
    tbb::parallel_for(size_t(0), chunks, [&](size_t c) {
      BuildRef* b = first + c * kChunk;
      BuildRef* e = first + std::min(n, (c + 1) * kChunk);
      BuildRef* const cut = partition<Axis>(m, split, b, e);
      cuts[c] = size_t(cut - b);
      chunk_lcb[c] = centroid_bounds(b, cut);
      chunk_rcb[c] = centroid_bounds(cut, e);
    });
    size_t left = 0;
    lcb = rcb = Box4::empty();
    for (size_t c = 0; c < chunks; ++c) {
      left += cuts[c];
      lcb.extend(chunk_lcb[c]);
      rcb.extend(chunk_rcb[c]);
    }
    // Misplaced runs, in order: right-side references before `left`, left-side ones from `left` on.
    struct Run {
      size_t begin, end;
    };
    std::vector<Run> wrong_r, wrong_l;
    for (size_t c = 0; c < chunks; ++c) {
      const size_t b = c * kChunk, e = std::min(n, (c + 1) * kChunk), k = b + cuts[c];
      if (std::min(e, left) > k) wrong_r.push_back({k, std::min(e, left)});  // right side, left of the cut
      if (k > std::max(b, left)) wrong_l.push_back({std::max(b, left), k});  // left side, right of the cut
    }
    // Swap the i-th misplaced reference of one list with the i-th of the other, in pieces of kChunk pairs.
    size_t total = 0;
    for (const Run& x : wrong_r) total += x.end - x.begin;
    const size_t pieces = (total + kChunk - 1) / kChunk;
    const auto len = [](const Run& x) { return x.end - x.begin; };
    tbb::parallel_for(size_t(0), pieces, [&](size_t p) {
      const size_t skip = p * kChunk;
      size_t count = std::min(total, skip + kChunk) - skip;
      size_t ri = 0, li = 0, ro = skip, lo = skip;  // run index and offset in it, per list
      while (ro >= len(wrong_r[ri])) ro -= len(wrong_r[ri++]);
      while (lo >= len(wrong_l[li])) lo -= len(wrong_l[li++]);
      while (count > 0) {
        const size_t step = std::min({count, len(wrong_r[ri]) - ro, len(wrong_l[li]) - lo});
        std::swap_ranges(first + wrong_r[ri].begin + ro, first + wrong_r[ri].begin + ro + step,
                         first + wrong_l[li].begin + lo);
        count -= step;
        ro += step;
        lo += step;
        if (ro == len(wrong_r[ri])) {
          ++ri;
          ro = 0;
        }
        if (lo == len(wrong_l[li])) {
          ++li;
          lo = 0;
        }
      }
    });
    return first + left;
  }

  // Ranges of at most kSmallSplit references are partitioned by partition_small() from the bin indices binning
  // computed (partition() would run finish_partition() alone on them).
  static constexpr uint32_t kSmallSplit = 128;

  // The permutation finish_partition() makes of refs [first, first + n) (references whose bin on `axis` is below
  // `split` first), without branching on the references: the i-th reference from the front that belongs on the
  // right is swapped with the i-th from the back that belongs on the left. Returns the left side's size.
  static uint32_t partition_small(BuildRef* first, uint32_t n, const int32_t (*bin)[4], int axis, int split) {
    uint32_t left = 0;
    for (uint32_t i = 0; i < n; ++i) left += bin[i][axis] < split;
    uint8_t wrong_r[kSmallSplit], wrong_l[kSmallSplit];  // right-side references before `left`, left-side ones after
    uint32_t nr = 0, nl = 0;
    for (uint32_t i = 0; i < left; ++i) {
      wrong_r[nr] = uint8_t(i);
      nr += bin[i][axis] >= split;
    }
    for (uint32_t i = n; i-- > left;) {
      wrong_l[nl] = uint8_t(i);
      nl += bin[i][axis] < split;
    }
    assert(nr == nl);
    for (uint32_t k = 0; k < nr; ++k) std::swap(first[wrong_r[k]], first[wrong_l[k]]);
    return left;
  }

  // Hoare partition of [lo, hi) with branches: for the small rest.
  template <int Axis>
  static BuildRef* finish_partition(const LeftOf<Axis>& left_of, BuildRef* lo, BuildRef* hi) {
    for (;;) {
      while (lo < hi && left_of(*lo)) ++lo;
      while (lo < hi && !left_of(*(hi - 1))) --hi;
      if (lo >= hi) return lo;
      std::swap(*lo, *(hi - 1));
      ++lo;
      --hi;
    }
  }

  // Bounds of the centroids of [first, last).
  static Box4 centroid_bounds(const BuildRef* first, const BuildRef* last) {
    Box4 a = Box4::empty(), b = Box4::empty();
    for (; last - first >= 2; first += 2) {
      a.extend(first[0].c2());
      b.extend(first[1].c2());
    }
    if (first != last) a.extend(first->c2());
    a.extend(b);
    return a;
  }

  // Decides whether r becomes a leaf (false) or is split (true, refs partitioned into l and rr).
  bool split(const Range& r, Range& l, Range& rr) {
    const uint32_t n = r.size();
    if (n == 1) return false;
    const uint32_t max_leaf = leaf_limit();
    // One packet's worth of primitives: a leaf is one packet test; no split can be cheaper than that.
    if (n <= max_leaf && n <= uint32_t(kPacketWidth)) return false;

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

    // Fewer bins for smaller ranges (4 + n / 16, at most opt.bins): small ranges are the most numerous, and their
    // cost is mostly per bin.
    const int nb = std::clamp(std::min(opt.bins, 4 + int(n / 16)), 2, kMaxBins);
    const BinMapper m(r.cbox, nb);
    // Small ranges keep every reference's bin indices for the partition.
    const bool small = n <= kSmallSplit;
    alignas(16) int32_t small_bins[kSmallSplit][4];
    Bins bins(nb);
    if (small) {
      bin_indices(m, refs.data() + r.begin, n, small_bins);
      bin_refs(bins, refs.data() + r.begin, n, small_bins);
    } else {
      bins = bin_range(m, nb, r.begin, r.end);
    }

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

    // Partition by bin; the boxes come from the bins, the centroid bounds from a pass over each side.
    BuildRef* const first = refs.data() + r.begin;
    BuildRef* const last = refs.data() + r.end;
    Box4 lcb, rcb;
    BuildRef* cut;
    if (small) {
      cut = first + partition_small(first, n, small_bins, best_axis, best_split);
      lcb = centroid_bounds(first, cut);
      rcb = centroid_bounds(cut, last);
    } else {
      cut = best_axis == 0   ? partition_any<0>(m, best_split, first, last, lcb, rcb)
            : best_axis == 1 ? partition_any<1>(m, best_split, first, last, lcb, rcb)
                             : partition_any<2>(m, best_split, first, last, lcb, rcb);
    }
    const uint32_t mid = uint32_t(cut - refs.data());
    if (mid == r.begin || mid == r.end) {  // unreachable with exact binning; stay safe
      halves(r, r.begin + n / 2, l, rr);
      return true;
    }
    l = Range{r.begin, mid, best_lbox.bounds(), lcb.bounds(), r.depth + 1};
    rr = Range{mid, r.end, best_rbox.bounds(), rcb.bounds(), r.depth + 1};
    return true;
  }

  // Packets of a leaf over refs[begin, end): triangles and spheres fill packets of their own.
  uint32_t leaf_packets(uint32_t begin, uint32_t end) const {
    const uint32_t nt = triangles_in(begin, end);
    return packets_for(nt) + packets_for(end - begin - nt);
  }

  // Number of triangles among refs[begin, end).
  uint32_t triangles_in(uint32_t begin, uint32_t end) const {
    const uint32_t ntri = bvh.num_triangles_;
    if (bvh.num_spheres_ == 0) return end - begin;
    uint32_t nt = 0;
    for (uint32_t i = begin; i < end; ++i) nt += refs[i].id < ntri;
    return nt;
  }

  // Writes refs[begin, end) as packets (triangles first, then spheres) from packets_[first] on and returns the
  // leaf's child reference.
  uint32_t emit_leaf(uint32_t begin, uint32_t end, uint32_t first) {
    const Range r{begin, end, {}, {}, 0};
    const uint32_t ntri = bvh.num_triangles_;
    const uint32_t nt = triangles_in(begin, end);
    const uint32_t ns = r.size() - nt;
    // Triangles before spheres inside the leaf, keeping their order otherwise.
    if (nt > 0 && ns > 0)
      std::stable_partition(refs.begin() + r.begin, refs.begin() + r.end,
                            [ntri](const BuildRef& x) { return x.id < ntri; });
    const uint32_t count = packets_for(nt) + packets_for(ns);
    Packet* out = bvh.packets_.data() + first;
    uint32_t i = r.begin;
    for (uint32_t p = 0; p < count; ++p) {
      Packet& pk = out[p];
      const bool tri = i < r.end && refs[i].id < ntri;
      for (int lane = 0; lane < kPacketWidth; ++lane) {
        if (i < r.end && (refs[i].id < ntri) == tri) {
          const uint32_t id = refs[i++].id;
          pk.id[lane] = id;
          if (tri) {
            const Triangle& t = triangles[id];
            const Vec3* v[3] = {&t.p0, &t.p1, &t.p2};
            for (int k = 0; k < 3; ++k) {
              pk.v[k][0][lane] = v[k]->x;
              pk.v[k][1][lane] = v[k]->y;
              pk.v[k][2][lane] = v[k]->z;
            }
          } else {
            const Sphere& s = spheres[id - ntri];
            pk.v[0][0][lane] = s.center.x;
            pk.v[0][1][lane] = s.center.y;
            pk.v[0][2][lane] = s.center.z;
            pk.v[1][0][lane] = s.radius;
            pk.v[1][1][lane] = pk.v[1][2][lane] = 0.f;
            for (int a = 0; a < 3; ++a) pk.v[2][a][lane] = 0.f;
          }
        } else {
          pk.id[lane] = kNoPrim;  // unused: zero data, masked out by its id
          for (int k = 0; k < 3; ++k)
            for (int a = 0; a < 3; ++a) pk.v[k][a][lane] = 0.f;
        }
      }
    }
    out[count - 1].id[0] |= kLastPacket;
    return kLeafBit | first;
  }

  // ---- Tiny scenes: one wide node over at most kNodeWidth leaves.
  //
  // Rays in a scene of a few dozen primitives (a room and what stands in it) mostly start inside it. There the
  // binned build's leaves, each mixing pieces of several walls to fill its packet, all span the room, so every ray
  // enters every leaf. Scenes of at most kTinyScene references are instead grouped bottom-up: the two groups whose
  // merge adds least to the sum over groups of packets times the area of the group's box are merged, as long as a
  // merge adds nothing or more than kNodeWidth groups remain, up to kTinyLeaf references a group. A room's walls so
  // become leaves of their own, flat boxes that only the rays reaching them enter.
  static constexpr size_t kTinyScene = size_t(kNodeWidth) * size_t(kPacketWidth);
  static constexpr uint32_t kTinyLeaf = 2 * uint32_t(kPacketWidth);

  // Builds the tiny layout over all references into bvh; false (nothing written) when they do not fit in
  // kNodeWidth groups.
  bool build_tiny() {
    const uint32_t ntri = bvh.num_triangles_;
    const auto packets = [](uint32_t tris, uint32_t others) { return packets_for(tris) + packets_for(others); };
    const auto cost = [&](const Bounds3& b, uint32_t tris, uint32_t others) {
      return float(packets(tris, others)) * b.surface_area();
    };
    struct Group {
      Bounds3 box;
      uint32_t tris = 0, others = 0;
      std::vector<uint32_t> refs;
      float cost = 0.f;  // cost(box, tris, others)
    };
    std::vector<Group> groups(refs.size());
    for (uint32_t i = 0; i < refs.size(); ++i) {
      const BuildRef& r = refs[i];
      Group& g = groups[i];
      g.box = Bounds3{Vec3(r.lo[0], r.lo[1], r.lo[2]), Vec3(r.hi[0], r.hi[1], r.hi[2])};
      (r.id < ntri ? g.tris : g.others) = 1;
      g.refs = {i};
      g.cost = cost(g.box, g.tris, g.others);
    }
    for (;;) {
      float best = kInfinity;
      size_t bi = 0, bj = 0;
      for (size_t i = 0; i < groups.size(); ++i)
        for (size_t j = i + 1; j < groups.size(); ++j) {
          if (groups[i].refs.size() + groups[j].refs.size() > kTinyLeaf) continue;
          Bounds3 u = groups[i].box;
          u.extend(groups[j].box);
          const float d = cost(u, groups[i].tris + groups[j].tris, groups[i].others + groups[j].others) -
                          groups[i].cost - groups[j].cost;
          if (d < best) {
            best = d;
            bi = i;
            bj = j;
          }
        }
      if (best == kInfinity) {
        if (groups.size() > size_t(kNodeWidth)) return false;
        break;
      }
      if (groups.size() <= size_t(kNodeWidth) && best > 0.f) break;
      Group& a = groups[bi];
      Group& b = groups[bj];
      a.box.extend(b.box);
      a.tris += b.tris;
      a.others += b.others;
      a.refs.insert(a.refs.end(), b.refs.begin(), b.refs.end());
      a.cost = cost(a.box, a.tris, a.others);
      groups.erase(groups.begin() + std::ptrdiff_t(bj));
    }
    // Leaves in the order of their first reference, references in input order.
    for (Group& gr : groups) std::sort(gr.refs.begin(), gr.refs.end());
    std::sort(groups.begin(), groups.end(), [](const Group& x, const Group& y) { return x.refs[0] < y.refs[0]; });
    const RefVector in(refs.begin(), refs.end());
    uint32_t w = 0, total = 0;
    for (const Group& gr : groups) {
      for (uint32_t i : gr.refs) refs[w++] = in[i];
      total += packets(gr.tris, gr.others);
    }
    bvh.packets_.resize(total);
    bvh.nodes_.resize(1);
    Node& node = bvh.nodes_[0];
    uint32_t begin = 0, next_packet = 0;
    for (size_t k = 0; k < groups.size(); ++k) {
      const uint32_t end = begin + uint32_t(groups[k].refs.size());
      set_slot(node, int(k), groups[k].box, emit_leaf(begin, end, next_packet));
      next_packet += packets(groups[k].tris, groups[k].others);
      begin = end;
    }
    clear_slots(node, int(groups.size()));
    return true;
  }

  // ---- The binary tree, and its collapse into the wide tree.
  //
  // The builder first makes a binary tree (every range split once, by split()), then chooses which of its inner
  // nodes become wide nodes, so that the sum of their areas (the expected number of wide node visits of a ray
  // through the root, by the surface area heuristic) is least with at most kNodeWidth children each; the leaves are
  // the binary leaves either way. A subtree's costs are the least cost of representing it in k = 1..kNodeWidth
  // slots of its parent: in one slot it is a leaf or a wide node, in more its children may share the slots.
  // (A wide tree built top-down by opening the largest child had half-empty nodes at the bottom: 4.2 children per
  // node against 6 here.)

  static constexpr uint32_t kNone = 0xffffffffu;
  using Costs = std::array<float, kNodeWidth>;  // cost of a subtree in k slots at index k - 1

  // Trivially constructible: the array is sized by an upper bound and only the used part may be touched.
  struct BinaryNode {
    float lo[3], hi[3];        // bounds
    uint32_t begin, end;       // references
    uint32_t left;             // children left and left + 1, kNone for a leaf
    uint32_t packets;          // leaf packets in the subtree
    uint32_t wide_nodes;       // wide nodes in the subtree when this node is one (itself included; 0 for a leaf)
    uint8_t pick[kNodeWidth];  // pick[0]: slots of left's forest when this is a wide node (right gets the rest);
                               // pick[k - 1], k >= 2: slots of left's forest in k slots, 0 when this takes one
    bool leaf() const { return left == kNone; }
    uint32_t right() const { return left + 1; }
    Bounds3 box() const { return Bounds3{Vec3(lo[0], lo[1], lo[2]), Vec3(hi[0], hi[1], hi[2])}; }
  };
  static_assert(std::is_trivially_default_constructible_v<BinaryNode>);

  std::vector<BinaryNode, detail::UninitAllocator<BinaryNode>> binary;
  std::atomic<uint32_t> next_binary{0};

  // The least-cost choices at inner node n (area a) from its children's costs; returns n's costs.
  static Costs collapse(BinaryNode& n, float a, const Costs& l, const Costs& r) {
    Costs c;
    float best = kInfinity;
    int best_a = 1;
    for (int k = 1; k < kNodeWidth; ++k) {
      const float x = l[size_t(k - 1)] + r[size_t(kNodeWidth - k - 1)];
      if (x < best) {
        best = x;
        best_a = k;
      }
    }
    c[0] = a + best;
    n.pick[0] = uint8_t(best_a);
    for (int k = 2; k <= kNodeWidth; ++k) {
      float bk = c[0];
      int ak = 0;
      for (int i = 1; i < k; ++i) {
        const float x = l[size_t(i - 1)] + r[size_t(k - i - 1)];
        if (x < bk) {
          bk = x;
          ak = i;
        }
      }
      c[size_t(k - 1)] = bk;
      n.pick[k - 1] = uint8_t(ak);
    }
    return c;
  }

  // Builds the binary tree over r into binary[idx] and below, with the choices of the wide tree and the sizes of
  // its parts; returns the subtree's costs.
  Costs build_binary(uint32_t idx, const Range& r) {
    BinaryNode& n = binary[idx];
    for (int a = 0; a < 3; ++a) {
      n.lo[a] = r.box.lo[a];
      n.hi[a] = r.box.hi[a];
    }
    n.begin = r.begin;
    n.end = r.end;
    Range a, b;
    if (!split(r, a, b)) {
      n.left = kNone;
      n.packets = leaf_packets(r.begin, r.end);
      n.wide_nodes = 0;
      return Costs{};  // a leaf costs the same wherever it hangs
    }
    const uint32_t li = next_binary.fetch_add(2, std::memory_order_relaxed);
    n.left = li;
    Costs cl, cr;
    if (a.size() > kParallelTaskThreshold && b.size() > kParallelTaskThreshold) {
      tbb::parallel_invoke([&] { cl = build_binary(li, a); }, [&] { cr = build_binary(li + 1, b); });
    } else {
      cl = build_binary(li, a);
      cr = build_binary(li + 1, b);
    }
    const Costs c = collapse(n, r.box.surface_area(), cl, cr);
    n.packets = binary[li].packets + binary[li + 1].packets;
    std::array<uint32_t, kNodeWidth> kids;
    const int nk = wide_children(n, kids);
    n.wide_nodes = 1;
    for (int k = 0; k < nk; ++k) n.wide_nodes += binary[kids[size_t(k)]].wide_nodes;
    return c;
  }

  // Appends to kids the roots of the forest that stands for subtree m in k slots.
  void expand(uint32_t m, int k, std::array<uint32_t, kNodeWidth>& kids, int& nk) const {
    const BinaryNode& n = binary[m];
    if (n.leaf() || k == 1 || n.pick[k - 1] == 0) {
      kids[size_t(nk++)] = m;
      return;
    }
    const int a = n.pick[k - 1];
    expand(n.left, a, kids, nk);
    expand(n.right(), k - a, kids, nk);
  }

  // The children of inner binary node n as a wide node, in order; returns their number.
  int wide_children(const BinaryNode& n, std::array<uint32_t, kNodeWidth>& kids) const {
    int nk = 0;
    expand(n.left, n.pick[0], kids, nk);
    expand(n.right(), kNodeWidth - n.pick[0], kids, nk);
    return nk;
  }

  static void set_slot(Node& node, int k, const Bounds3& b, uint32_t child) {
    for (int ax = 0; ax < 3; ++ax) {
      node.box[2 * ax][k] = b.lo[ax];
      node.box[2 * ax + 1][k] = b.hi[ax];
    }
    node.child[k] = child;
  }

  // Fills slots [from, kNodeWidth) with empty boxes (lo +inf, hi -inf), which no ray enters, and zeroes the padding.
  static void clear_slots(Node& node, int from) {
    for (int k = from; k < kNodeWidth; ++k) set_slot(node, k, Bounds3{}, 0);
    std::fill(std::begin(node.pad), std::end(node.pad), 0u);
  }

  // Writes wide node idx for inner binary node m and, recursively (in parallel for large subtrees), everything below.
  // Every subtree has ranges of its own, so the layout does not depend on the threads: the node's inner children
  // are nodes [kid_base, kid_base + number of them), followed by their subtrees' other nodes in order; the leaves'
  // packets are packets [packet_base, packet_base + n.packets) in order.
  void emit_node(uint32_t idx, uint32_t m, uint32_t kid_base, uint32_t packet_base) {
    const BinaryNode& n = binary[m];
    std::array<uint32_t, kNodeWidth> kids;
    const int nk = wide_children(n, kids);

    struct Job {
      uint32_t node, binary, kid_base, packet_base;
    };
    std::array<Job, kNodeWidth> jobs;
    int nj = 0;
    for (int k = 0; k < nk; ++k) nj += !binary[kids[size_t(k)]].leaf();
    uint32_t next_kid = kid_base, next_desc = kid_base + uint32_t(nj), next_packet = packet_base;
    nj = 0;
    Node& node = bvh.nodes_[idx];
    for (int k = 0; k < nk; ++k) {
      const BinaryNode& c = binary[kids[size_t(k)]];
      if (c.leaf()) {
        set_slot(node, k, c.box(), emit_leaf(c.begin, c.end, next_packet));
      } else {
        jobs[size_t(nj++)] = Job{next_kid, kids[size_t(k)], next_desc, next_packet};
        set_slot(node, k, c.box(), next_kid++);
        next_desc += c.wide_nodes - 1;
      }
      next_packet += c.packets;
    }
    clear_slots(node, nk);

    tbb::task_group tg;
    bool spawned = false;
    for (int j = 0; j < nj; ++j) {
      const Job job = jobs[size_t(j)];
      const BinaryNode& c = binary[job.binary];
      if (c.end - c.begin > kParallelTaskThreshold) {
        tg.run([this, job] { emit_node(job.node, job.binary, job.kid_base, job.packet_base); });
        spawned = true;
      } else {
        emit_node(job.node, job.binary, job.kid_base, job.packet_base);
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
          // Whole 16-byte stores (the bounds are not read back: a load spanning several narrower stores stalls).
          const uint32_t id = ok ? uint32_t(i) : kNoPrim;
          const __m128 lo = _mm_setr_ps(box.lo.x, box.lo.y, box.lo.z, std::bit_cast<float>(id));
          const __m128 hi = _mm_setr_ps(box.hi.x, box.hi.y, box.hi.z, 0.f);
          _mm_store_ps(r.lo, lo);
          _mm_store_ps(r.hi, hi);
          if (!ok) {
            ++a.dropped;
            continue;
          }
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
  Range root_range;
  root_range.box = acc.box.bounds();
  root_range.cbox = acc.cbox.bounds();
  root_range.begin = 0;
  root_range.end = uint32_t(refs.size());
  bvh.bounds_ = root_range.box;

  const size_t n = refs.size();
  Builder b(options, refs, triangles, spheres, bvh);
  if (n <= Builder::kTinyScene && options.split == SplitMethod::kSah && b.build_tiny()) return bvh;
  // A binary tree over n references has at most 2n - 1 nodes; only the used part is touched.
  b.binary.resize(2 * n);
  b.next_binary.store(1);
  b.build_binary(0, root_range);
  // The output is sized exactly and written once, each subtree into ranges of its own (emit_node()).
  const Builder::BinaryNode& root = b.binary[0];
  bvh.packets_.resize(root.packets);
  if (root.leaf()) {
    // The whole scene is one leaf: a root with a single child.
    bvh.nodes_.resize(1);
    Node& node = bvh.nodes_[0];
    Builder::set_slot(node, 0, root_range.box, b.emit_leaf(root.begin, root.end, 0));
    Builder::clear_slots(node, 1);
  } else {
    bvh.nodes_.resize(root.wide_nodes);
    b.emit_node(0, 0, 1, 0);
  }
  return bvh;
}

// ------------------------------------------------------------------------------------------------------------
// Queries: per-ray constants here, traversal in the kernels of the chosen SimdPath (core/geometry/kernels/bvh_kernels.h).

namespace bvh_kernels {

bool sphere_hit(const Ray& ray, float cx, float cy, float cz, float radius, float tmax, float* t) {
  const auto th = intersect_sphere(Sphere{Vec3(cx, cy, cz), radius}, ray, tmax);
  if (!th) return false;
  *t = *th;
  return true;
}

}  // namespace bvh_kernels

namespace {

const bvh_kernels::Kernels& kernels_of(SimdPath p) {
  static const bvh_kernels::Kernels* const table[] = {&bvh_kernels::kSse2, &bvh_kernels::kAvx2,
                                                      &bvh_kernels::kAvx512};
  return *table[size_t(p)];
}

bvh_kernels::RayData ray_data(const Ray& r) {
  return bvh_kernels::RayData{{r.o.x, r.o.y, r.o.z}, {r.d.x, r.d.y, r.d.z}, r.tmax, &r};
}

}  // namespace

void Bvh::set_simd_path(SimdPath p) {
  if (!simd_path_supported(p))
    throw std::invalid_argument("Bvh: this CPU cannot run the " + std::string(kSimdPathNames[size_t(p)]) +
                                " kernels");
  path_ = p;
}

std::optional<Hit> Bvh::intersect(const Ray& ray) const {
  if (nodes_.empty()) return std::nullopt;
  const bvh_kernels::Tree tree{nodes_.data(), packets_.data(), num_triangles_, 1.f + 2.f * gamma(3)};
  bvh_kernels::HitRecord h;
  if (!kernels_of(path_).intersect(tree, ray_data(ray), &h)) return std::nullopt;
  return Hit{h.t, h.b1, h.b2, h.prim};
}

bool Bvh::occluded(const Ray& ray) const {
  if (nodes_.empty()) return false;
  const bvh_kernels::Tree tree{nodes_.data(), packets_.data(), num_triangles_, 1.f + 2.f * gamma(3)};
  return kernels_of(path_).occluded(tree, ray_data(ray));
}

size_t Bvh::memory_bytes() const { return nodes_.size() * sizeof(Node) + packets_.size() * sizeof(Packet); }

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
        for (int k = 0; k < kPacketWidth; ++k) prims += pk->id[k] != kNoPrim;
        if (pk->id[0] & kLastPacket) break;
      }
      cost += it.rel * double(prims);
      continue;
    }
    cost += it.rel;
    const Node& n = nodes_[it.ref];
    for (int k = 0; k < kNodeWidth; ++k) {
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
