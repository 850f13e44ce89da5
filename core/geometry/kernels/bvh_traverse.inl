// The BVH traversal kernels' source, compiled once per SimdPath: core/geometry/kernels/bvh_sse2.cpp, bvh_avx2.cpp and bvh_avx512.cpp
// each include <immintrin.h> and then this file inside their own namespace, with their instruction set's flags.
// Everything here has internal linkage (an unnamed namespace) and uses no library templates, so no function
// compiled for a wide instruction set can be picked by the linker for code that runs on a narrower CPU.
//
// The rules every path follows, so that all return bitwise the same hit (core/geometry/kernels/bvh_kernels.h):
// * The same slab test per lane: slab_test()'s operations (core/geometry/bounds.h), except that the far distance multiplies by
//   1/d and 1 + 2 gamma(3) premultiplied (one rounding more, still at least the exact distance: the four
//   roundings shrink it by at most (1 - 2^-24)^4, which 1 + 2 gamma(3) more than makes up).
// * Children visited nearest first by the same sort keys (entry distance, then slot); the same stack discipline
//   and pop-time culling.
// * Triangle tests per lane with exactly intersect_triangle()'s operations (core/geometry/triangle.h) and the same
//   double-precision fallback.
// * The closest hit is the least (t, primitive id): of hits at the same distance the lowest id wins, so the answer
//   depends neither on the tree's shape nor on the order in which leaves and lanes are met.

namespace {

using bvh_layout::kLastPacket;
using bvh_layout::kLeafBit;
using bvh_layout::kNodeWidth;
using bvh_layout::kNoPrim;
using bvh_layout::kPacketWidth;
using bvh_layout::Node;
using bvh_layout::Packet;

static_assert(kNodeWidth == 8 && kPacketWidth == 8);

inline int lowest(unsigned m) { return __builtin_ctz(m); }

// The double-precision finish of the watertight test, compiled here (no call: a call would make the compiler save
// every vector register around the leaf loop).
#include "core/util/sheared_double.h"

// Vector operations on eight lanes. The slab test per lane (node_test below): near and far planes chosen by the
// direction's sign, (plane - o) * inv_d for the near distance and (plane - o) * (inv_d (1 + 2 gamma(3))) for the far
// one, and max/min that keep the running value when the new distance is NaN (MAXPS/MINPS return their second
// operand on unordered inputs). The entry distance is therefore in [0, +inf] and never NaN.
#if defined(__AVX2__)
using VF = __m256;
inline VF vset1(float x) { return _mm256_set1_ps(x); }
inline VF vload(const float* p) { return _mm256_load_ps(p); }
inline VF vsub(VF a, VF b) { return _mm256_sub_ps(a, b); }
inline VF vmul(VF a, VF b) { return _mm256_mul_ps(a, b); }
inline VF vmax(VF a, VF b) { return _mm256_max_ps(a, b); }
inline VF vmin(VF a, VF b) { return _mm256_min_ps(a, b); }
inline VF vadd(VF a, VF b) { return _mm256_add_ps(a, b); }
inline VF vdiv(VF a, VF b) { return _mm256_div_ps(a, b); }
inline VF vand(VF a, VF b) { return _mm256_and_ps(a, b); }
inline VF vor(VF a, VF b) { return _mm256_or_ps(a, b); }
inline VF vxor(VF a, VF b) { return _mm256_xor_ps(a, b); }
inline VF veq(VF a, VF b) { return _mm256_cmp_ps(a, b, _CMP_EQ_OQ); }
inline VF vlt(VF a, VF b) { return _mm256_cmp_ps(a, b, _CMP_LT_OQ); }
inline VF vgt(VF a, VF b) { return _mm256_cmp_ps(a, b, _CMP_GT_OQ); }
inline VF vle(VF a, VF b) { return _mm256_cmp_ps(a, b, _CMP_LE_OQ); }
inline VF vbits(uint32_t x) { return _mm256_castsi256_ps(_mm256_set1_epi32(int(x))); }
inline unsigned vmask(VF a) { return unsigned(_mm256_movemask_ps(a)); }
inline void vstore(float* p, VF a) { _mm256_store_ps(p, a); }
// Mask of the lanes whose id is not kNoPrim.
inline unsigned vvalid(const uint32_t* id) {
  const __m256i ids = _mm256_load_si256(reinterpret_cast<const __m256i*>(id));
  return unsigned(_mm256_movemask_ps(_mm256_castsi256_ps(_mm256_cmpeq_epi32(ids, _mm256_set1_epi32(-1))))) ^ 0xffu;
}
#if defined(__AVX512VL__)
inline unsigned vle_mask(VF a, VF b) { return _cvtmask8_u32(_mm256_cmp_ps_mask(a, b, _CMP_LE_OQ)); }
#else
inline unsigned vle_mask(VF a, VF b) { return unsigned(_mm256_movemask_ps(_mm256_cmp_ps(a, b, _CMP_LE_OQ))); }
#endif
// Sort keys of the eight entry distances: the distance's bits with the slot in the three lowest (distances are
// non-negative, so their bits order like the floats).
inline void vkeys(VF t, uint32_t* keys) {
  const __m256i k = _mm256_or_si256(_mm256_and_si256(_mm256_castps_si256(t), _mm256_set1_epi32(~7)),
                                    _mm256_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7));
  _mm256_store_si256(reinterpret_cast<__m256i*>(keys), k);
}
#else
// Two SSE halves, lanes 0-3 and 4-7, with the same per-lane operations.
struct VF {
  __m128 lo, hi;
};
inline VF vset1(float x) { return VF{_mm_set1_ps(x), _mm_set1_ps(x)}; }
inline VF vload(const float* p) { return VF{_mm_load_ps(p), _mm_load_ps(p + 4)}; }
inline VF vsub(VF a, VF b) { return VF{_mm_sub_ps(a.lo, b.lo), _mm_sub_ps(a.hi, b.hi)}; }
inline VF vmul(VF a, VF b) { return VF{_mm_mul_ps(a.lo, b.lo), _mm_mul_ps(a.hi, b.hi)}; }
inline VF vmax(VF a, VF b) { return VF{_mm_max_ps(a.lo, b.lo), _mm_max_ps(a.hi, b.hi)}; }
inline VF vmin(VF a, VF b) { return VF{_mm_min_ps(a.lo, b.lo), _mm_min_ps(a.hi, b.hi)}; }
inline VF vadd(VF a, VF b) { return VF{_mm_add_ps(a.lo, b.lo), _mm_add_ps(a.hi, b.hi)}; }
inline VF vdiv(VF a, VF b) { return VF{_mm_div_ps(a.lo, b.lo), _mm_div_ps(a.hi, b.hi)}; }
inline VF vand(VF a, VF b) { return VF{_mm_and_ps(a.lo, b.lo), _mm_and_ps(a.hi, b.hi)}; }
inline VF vor(VF a, VF b) { return VF{_mm_or_ps(a.lo, b.lo), _mm_or_ps(a.hi, b.hi)}; }
inline VF vxor(VF a, VF b) { return VF{_mm_xor_ps(a.lo, b.lo), _mm_xor_ps(a.hi, b.hi)}; }
inline VF veq(VF a, VF b) { return VF{_mm_cmpeq_ps(a.lo, b.lo), _mm_cmpeq_ps(a.hi, b.hi)}; }
inline VF vlt(VF a, VF b) { return VF{_mm_cmplt_ps(a.lo, b.lo), _mm_cmplt_ps(a.hi, b.hi)}; }
inline VF vgt(VF a, VF b) { return VF{_mm_cmpgt_ps(a.lo, b.lo), _mm_cmpgt_ps(a.hi, b.hi)}; }
inline VF vle(VF a, VF b) { return VF{_mm_cmple_ps(a.lo, b.lo), _mm_cmple_ps(a.hi, b.hi)}; }
inline VF vbits(uint32_t x) {
  const __m128 v = _mm_castsi128_ps(_mm_set1_epi32(int(x)));
  return VF{v, v};
}
inline unsigned vmask(VF a) {
  return unsigned(_mm_movemask_ps(a.lo)) | unsigned(_mm_movemask_ps(a.hi)) << 4;
}
inline void vstore(float* p, VF a) {
  _mm_store_ps(p, a.lo);
  _mm_store_ps(p + 4, a.hi);
}
inline unsigned vvalid(const uint32_t* id) {
  const __m128i none = _mm_set1_epi32(-1);
  const __m128i lo = _mm_load_si128(reinterpret_cast<const __m128i*>(id));
  const __m128i hi = _mm_load_si128(reinterpret_cast<const __m128i*>(id + 4));
  return (unsigned(_mm_movemask_ps(_mm_castsi128_ps(_mm_cmpeq_epi32(lo, none)))) |
          unsigned(_mm_movemask_ps(_mm_castsi128_ps(_mm_cmpeq_epi32(hi, none)))) << 4) ^ 0xffu;
}
inline unsigned vle_mask(VF a, VF b) {
  return unsigned(_mm_movemask_ps(_mm_cmple_ps(a.lo, b.lo))) |
         unsigned(_mm_movemask_ps(_mm_cmple_ps(a.hi, b.hi))) << 4;
}
inline void vkeys(VF t, uint32_t* keys) {
  const __m128i m = _mm_set1_epi32(~7);
  _mm_store_si128(reinterpret_cast<__m128i*>(keys),
                  _mm_or_si128(_mm_and_si128(_mm_castps_si128(t.lo), m), _mm_setr_epi32(0, 1, 2, 3)));
  _mm_store_si128(reinterpret_cast<__m128i*>(keys + 4),
                  _mm_or_si128(_mm_and_si128(_mm_castps_si128(t.hi), m), _mm_setr_epi32(4, 5, 6, 7)));
}
#endif

// Ray::valid() (core/geometry/ray.h) and the per-ray constants of BoxRay (core/geometry/bounds.h) and WatertightRay
// (core/geometry/triangle.h), bitwise: the same IEEE divisions, lane by lane.
struct RaySetup {
  // Slab test.
  VF o[3], inv_d[3], inv_d_far[3];  // inv_d_far: inv_d * (1 + 2 gamma(3)), rounded
  long near_off[3], far_off[3];  // byte offsets in a Node of the rows holding each axis's near and far planes
  // Watertight test.
  int kx, ky, kz;
  VF ox, oy, oz, sx, sy, sz;
  float sz1;  // sz as a scalar, for the double-precision fallback
  float tmax;
  const Ray* ray;
};

inline bool setup(const Tree& tree, const RayData& in, RaySetup& s) {
  const __m128 o = _mm_setr_ps(in.o[0], in.o[1], in.o[2], 0.f);
  const __m128 d = _mm_setr_ps(in.d[0], in.d[1], in.d[2], 1.f);
  const __m128 abs_mask = _mm_castsi128_ps(_mm_set1_epi32(0x7fffffff));
  const __m128 largest = _mm_castsi128_ps(_mm_set1_epi32(0x7f7fffff));
  const int finite = _mm_movemask_ps(_mm_and_ps(_mm_cmple_ps(_mm_and_ps(o, abs_mask), largest),
                                                _mm_cmple_ps(_mm_and_ps(d, abs_mask), largest)));
  const int nonzero = _mm_movemask_ps(_mm_cmpneq_ps(d, _mm_setzero_ps())) & 7;
  if (finite != 0xf || !nonzero || in.tmax != in.tmax) return false;

  const __m128 inv = _mm_div_ps(_mm_set1_ps(1.f), d);  // BoxRay: 1.f / d per component
  const int neg = _mm_movemask_ps(inv);                // BoxRay::neg
  alignas(16) float inv_d[4];
  _mm_store_ps(inv_d, inv);
  for (int a = 0; a < 3; ++a) {
    s.o[a] = vset1(in.o[a]);
    s.inv_d[a] = vset1(inv_d[a]);
    const int n = (neg >> a) & 1;
    s.near_off[a] = long(2 * a + n) * long(sizeof(Node::box[0]));
    s.far_off[a] = long(2 * a + 1 - n) * long(sizeof(Node::box[0]));
  }
  for (int a = 0; a < 3; ++a) s.inv_d_far[a] = vset1(inv_d[a] * tree.far_scale);

  // WatertightRay: kz the largest |d| (the first on ties), kx and ky the next axes cyclically, swapped when
  // d[kz] < 0; shear constants d[kx] / d[kz], d[ky] / d[kz] and 1 / d[kz].
  const float ax = __builtin_fabsf(in.d[0]), ay = __builtin_fabsf(in.d[1]), az = __builtin_fabsf(in.d[2]);
  static constexpr int8_t kLargest[8] = {2, 1, 2, 1, 2, 2, 0, 0};  // (ax >= ay) * 4 + (ax >= az) * 2 + (ay >= az)
  static constexpr int8_t kNext[3][2][2] = {{{1, 2}, {2, 1}}, {{2, 0}, {0, 2}}, {{0, 1}, {1, 0}}};
  const int kz = kLargest[(ax >= ay) * 4 + (ax >= az) * 2 + (ay >= az)];
  const float dz = in.d[kz];
  const int nz = dz < 0.f ? 1 : 0;
  s.kx = kNext[kz][nz][0];
  s.ky = kNext[kz][nz][1];
  s.kz = kz;
  alignas(16) float shear[4];
  _mm_store_ps(shear, _mm_div_ps(_mm_setr_ps(in.d[s.kx], in.d[s.ky], 1.f, 1.f), _mm_set1_ps(dz)));
  s.ox = vset1(in.o[s.kx]);
  s.oy = vset1(in.o[s.ky]);
  s.oz = vset1(in.o[kz]);
  s.sx = vset1(shear[0]);
  s.sy = vset1(shear[1]);
  s.sz = vset1(shear[2]);
  s.sz1 = shear[2];
  s.tmax = in.tmax;
  s.ray = in.ray;
  return true;
}

// Slab test of a node's eight child boxes against (0, tmax); returns the mask of boxes entered and their entry
// distances.
inline const float* row(const Node& n, long off) {
  return reinterpret_cast<const float*>(reinterpret_cast<const char*>(&n) + off);
}

[[gnu::always_inline]] inline unsigned node_test(const Node& n, const RaySetup& r, VF tmax, VF* t_entry) {
  VF t0 = vset1(0.f), t1 = tmax;
  for (int a = 0; a < 3; ++a) {
    const VF tn = vmul(vsub(vload(row(n, r.near_off[a])), r.o[a]), r.inv_d[a]);
    const VF tf = vmul(vsub(vload(row(n, r.far_off[a])), r.o[a]), r.inv_d_far[a]);
    t0 = vmax(tn, t0);  // tn > t0 ? tn : t0
    t1 = vmin(tf, t1);  // tf < t1 ? tf : t1
  }
  *t_entry = t0;
  return vle_mask(t0, t1);
}

// Results of eight triangle tests: t and the barycentrics of p1 and p2 for the lanes that hit.
struct Lanes8 {
  alignas(32) float t[8];
  alignas(32) float b1[8];
  alignas(32) float b2[8];
};

// The watertight test (core/geometry/triangle.h) on the eight triangles of a packet, lane by lane with the same operations
// in the same order, so t and the barycentrics are bitwise those of intersect_triangle(). Lanes whose float edge
// functions are zero or whose determinant is not finite go to the same double-precision fallback. `valid` is the
// mask of used lanes. Returns the mask of lanes that hit in (0, tmax); fills `out` for them when given (with no
// `out`, it may stop at the first hit).
[[gnu::always_inline]] inline unsigned triangles8(const Packet& pk, unsigned valid, const RaySetup& r, float tmax,
                                                  Lanes8* out) {
  const RaySetup& w = r;
  const auto& v = pk.v;
  const VF az = vsub(vload(v[0][w.kz]), r.oz);
  const VF bz = vsub(vload(v[1][w.kz]), r.oz);
  const VF cz = vsub(vload(v[2][w.kz]), r.oz);
  const VF ax = vsub(vsub(vload(v[0][w.kx]), r.ox), vmul(r.sx, az));
  const VF ay = vsub(vsub(vload(v[0][w.ky]), r.oy), vmul(r.sy, az));
  const VF bx = vsub(vsub(vload(v[1][w.kx]), r.ox), vmul(r.sx, bz));
  const VF by = vsub(vsub(vload(v[1][w.ky]), r.oy), vmul(r.sy, bz));
  const VF cx = vsub(vsub(vload(v[2][w.kx]), r.ox), vmul(r.sx, cz));
  const VF cy = vsub(vsub(vload(v[2][w.ky]), r.oy), vmul(r.sy, cz));

  const VF e0 = vsub(vmul(bx, cy), vmul(by, cx));
  const VF e1 = vsub(vmul(cx, ay), vmul(cy, ax));
  const VF e2 = vsub(vmul(ax, by), vmul(ay, bx));
  const VF det = vadd(vadd(e0, e1), e2);

  // Fallback lanes: an edge function is zero, or the determinant is not finite (|det| > FLT_MAX, or NaN).
  const VF zero = vset1(0.f);
  const unsigned fallback =
      vmask(vor(vor(vor(veq(e0, zero), veq(e1, zero)), veq(e2, zero)),
                vgt(vand(det, vbits(0x7fffffffu)), vbits(0x7f7fffffu)))) |
      (vmask(veq(det, det)) ^ 0xffu);
  const unsigned fb = fallback & valid;
  // Elsewhere all three are finite and non-zero: the signs are mixed exactly when a sign bit differs.
  const unsigned mixed = vmask(vor(vxor(e0, e1), vxor(e0, e2)));
  unsigned hit = valid & ~fallback & ~mixed;
  if (!hit && !fb) return 0;

  if (hit) {
    const VF inv_det = vdiv(vset1(1.f), det);
    const VF szaz = vmul(r.sz, az), szbz = vmul(r.sz, bz), szcz = vmul(r.sz, cz);
    const VF t = vmul(vadd(vadd(vmul(e0, szaz), vmul(e1, szbz)), vmul(e2, szcz)), inv_det);
    hit &= vmask(vand(vgt(t, zero), vlt(t, vset1(tmax))));
    if (out && hit) {
      vstore(out->t, t);
      vstore(out->b1, vmul(e1, inv_det));
      vstore(out->b2, vmul(e2, inv_det));
    }
  }
  if (fb) {
    alignas(32) float s[9][8];
    vstore(s[0], ax); vstore(s[1], ay); vstore(s[2], az);
    vstore(s[3], bx); vstore(s[4], by); vstore(s[5], bz);
    vstore(s[6], cx); vstore(s[7], cy); vstore(s[8], cz);
    for (unsigned m = fb; m; m &= m - 1) {
      const int k = lowest(m);
      const float sh[9] = {s[0][k], s[1][k], s[2][k], s[3][k], s[4][k], s[5][k], s[6][k], s[7][k], s[8][k]};
      float t, b0, b1, b2;
      if (finish_sheared_double(sh, w.sz1, tmax, &t, &b0, &b1, &b2)) {
        hit |= 1u << k;
        if (!out) return hit;
        out->t[k] = t;
        out->b1[k] = b1;
        out->b2[k] = b2;
      }
    }
  }
  return hit;
}

// Asks for the cache lines a child reference will touch first: a node's four lines or most of a leaf's first packet.
inline void prefetch_child(uint32_t ref, const Tree& tree) {
  const char* p = (ref & kLeafBit) ? reinterpret_cast<const char*>(tree.packets + (ref & ~kLeafBit))
                                   : reinterpret_cast<const char*>(tree.nodes + ref);
  _mm_prefetch(p, _MM_HINT_T0);
  _mm_prefetch(p + 64, _MM_HINT_T0);
  _mm_prefetch(p + 128, _MM_HINT_T0);
  _mm_prefetch(p + 192, _MM_HINT_T0);
}

struct StackEntry {
  uint32_t ref;
  float t;  // entry distance when pushed, its three lowest bits cleared (never above the exact entry distance)
};

// Deep enough for any tree the builder makes (kMaxDepth levels, kNodeWidth - 1 pushes each).
constexpr int kStackSize = (kNodeWidth - 1) * bvh_layout::kMaxDepth + 4;

inline float key_distance(uint32_t key) { return __builtin_bit_cast(float, key & ~7u); }

// Sorts n keys (distinct: each carries its slot) in descending order, so the nearest child comes last.
inline void sort_descending(uint32_t* k, int n) {
  for (int i = 1; i < n; ++i) {
    const uint32_t x = k[i];
    int j = i;
    for (; j > 0 && k[j - 1] < x; --j) k[j] = k[j - 1];
    k[j] = x;
  }
}

// Once a hit at t is found, boxes and primitives are tested against tmax = t (1 + 2^-20), not t: a box holding the
// hit point may compute its entry distance a few roundings beyond the hit's computed t (where walls meet, for one),
// and a hit at the same t with a lower id must still be found (for a normal t the product exceeds t by at least
// 7 ulps). Primitives found beyond t are rejected by better().
constexpr float kCullSlack = 1.f + 0x1p-20f;

// Whether a hit at (t, id) beats the closest so far, `best`: nearer, or as near with a lower id.
inline bool better(float t, uint32_t id, const HitRecord& best) {
  return t < best.t || (t == best.t && id < best.prim);
}

// The closest hit, the least (t, id). Children are visited nearest first by their sort keys (entry distance, then
// slot), the others pushed farthest first; a popped entry whose entry distance lies beyond tmax (the closest hit so
// far with its slack) is dropped.
bool intersect(const Tree& tree, const RayData& in, HitRecord* out) {
  RaySetup ray;
  if (!setup(tree, in, ray)) return false;
  const RaySetup& sr = ray;
  const RaySetup& tr = ray;
  float tmax = ray.tmax;
  HitRecord best{tmax, 0.f, 0.f, kNoPrim};
  bool found = false;

  StackEntry stack[kStackSize];
  int sp = 0;
  uint32_t ref = 0;
  for (;;) {
    while (!(ref & kLeafBit)) {
      const Node& n = tree.nodes[ref];
      VF tn;
      const unsigned mask = node_test(n, sr, vset1(tmax), &tn);
      if (mask == 0) goto pop;
      const unsigned rest = mask & (mask - 1);
      if (rest == 0) {
        ref = n.child[lowest(mask)];
        continue;
      }
      alignas(32) uint32_t keys[8];
      vkeys(tn, keys);
      if ((rest & (rest - 1)) == 0) {
        // Two boxes: visit the nearer first.
        uint32_t near = keys[lowest(mask)], far = keys[lowest(rest)];
        if (far < near) {
          const uint32_t x = near;
          near = far;
          far = x;
        }
        const uint32_t fref = n.child[far & 7];
        stack[sp++] = {fref, key_distance(far)};
        prefetch_child(fref, tree);
        ref = n.child[near & 7];
        continue;
      }
      // Three or more: sort by key, push the farthest first, visit the nearest now.
      uint32_t k[8];
      int ne = 0;
      for (unsigned m = mask; m; m &= m - 1) k[ne++] = keys[lowest(m)];
      sort_descending(k, ne);
      for (int i = 0; i < ne - 1; ++i) {
        const uint32_t c = n.child[k[i] & 7];
        stack[sp++] = {c, key_distance(k[i])};
        prefetch_child(c, tree);
      }
      ref = n.child[k[ne - 1] & 7];
    }
    // Leaf.
    for (const Packet* pk = tree.packets + (ref & ~kLeafBit);; ++pk) {
      const uint32_t id0 = pk->id[0] & ~kLastPacket;
      const unsigned valid = vvalid(pk->id);
      if (id0 < tree.num_triangles) {
        Lanes8 lanes;
        for (unsigned m = triangles8(*pk, valid, tr, tmax, &lanes); m; m &= m - 1) {
          const int k = lowest(m);
          if (better(lanes.t[k], k == 0 ? id0 : pk->id[k], best)) {
            best = HitRecord{lanes.t[k], lanes.b1[k], lanes.b2[k], k == 0 ? id0 : pk->id[k]};
            tmax = best.t * kCullSlack;
            found = true;
          }
        }
      } else {
        for (unsigned m = valid; m; m &= m - 1) {
          const int k = lowest(m);
          float th;
          const uint32_t id = k == 0 ? id0 : pk->id[k];
          if (sphere_hit(*ray.ray, pk->v[0][0][k], pk->v[0][1][k], pk->v[0][2][k], pk->v[1][0][k], tmax, &th) &&
              better(th, id, best)) {
            best = HitRecord{th, 0.f, 0.f, id};
            tmax = best.t * kCullSlack;
            found = true;
          }
        }
      }
      if (pk->id[0] & kLastPacket) break;
    }
  pop:
    for (;;) {
      if (sp == 0) {
        if (found) *out = best;
        return found;
      }
      const StackEntry& e = stack[--sp];
      if (e.t <= tmax) {  // the slab test against the shortened ray, given it passed against the longer one
        ref = e.ref;
        break;
      }
    }
  }
}

// Any hit: children in slot order, stopping at the first hit (the answer does not depend on the order).
bool occluded(const Tree& tree, const RayData& in) {
  RaySetup ray;
  if (!setup(tree, in, ray)) return false;
  const RaySetup& sr = ray;
  const RaySetup& tr = ray;
  const float tmax = ray.tmax;
  const VF tmax8 = vset1(tmax);

  uint32_t stack[kStackSize];
  int sp = 0;
  uint32_t ref = 0;
  for (;;) {
    while (!(ref & kLeafBit)) {
      const Node& n = tree.nodes[ref];
      VF tn;
      unsigned mask = node_test(n, sr, tmax8, &tn);
      if (mask == 0) goto pop;
      ref = n.child[lowest(mask)];
      for (mask &= mask - 1; mask; mask &= mask - 1) {
        const uint32_t c = n.child[lowest(mask)];
        stack[sp++] = c;
        prefetch_child(c, tree);
      }
    }
    for (const Packet* pk = tree.packets + (ref & ~kLeafBit);; ++pk) {
      const unsigned valid = vvalid(pk->id);
      if ((pk->id[0] & ~kLastPacket) < tree.num_triangles) {
        if (triangles8(*pk, valid, tr, tmax, nullptr)) return true;
      } else {
        for (unsigned m = valid; m; m &= m - 1) {
          const int k = lowest(m);
          float th;
          if (sphere_hit(*ray.ray, pk->v[0][0][k], pk->v[0][1][k], pk->v[0][2][k], pk->v[1][0][k], tmax, &th))
            return true;
        }
      }
      if (pk->id[0] & kLastPacket) break;
    }
  pop:
    if (sp == 0) return false;
    ref = stack[--sp];
  }
}

}  // namespace
