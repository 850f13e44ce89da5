// The BVH traversal kernels' source, compiled once per SimdPath: core/bvh_sse2.cpp, bvh_avx2.cpp and bvh_avx512.cpp
// each include <immintrin.h> and then this file inside their own namespace, with their instruction set's flags.
// Everything here has internal linkage (an unnamed namespace) and uses no library templates, so no function
// compiled for a wide instruction set can be picked by the linker for code that runs on a narrower CPU.
//
// The rules every path follows, so that all return bitwise the same hit (core/bvh_kernels.h):
// * Slab tests per lane with exactly slab_test()'s operations (core/bounds.h).
// * Children visited nearest first by the same sort keys (entry distance, then slot); the same stack discipline
//   and pop-time culling.
// * Triangle tests per lane with exactly intersect_triangle()'s operations (core/triangle.h), lanes accepted in
//   order with t < tmax, and the same double-precision fallback.

namespace {

using bvh_layout::kLastPacket;
using bvh_layout::kLeafBit;
using bvh_layout::kNodeWidth;
using bvh_layout::kNoPrim;
using bvh_layout::kPacketWidth;
using bvh_layout::Node;
using bvh_layout::Packet;

static_assert(kNodeWidth == 8 && kPacketWidth == 4);

inline int lowest(unsigned m) { return __builtin_ctz(m); }

// Per-ray constants of the slab test. The arithmetic per lane is slab_test()'s (core/bounds.h): near and far planes
// chosen by the direction's sign, (plane - o) * inv_d, the far distance scaled by 1 + 2 gamma(3), and max/min that
// keep the running value when the new distance is NaN (MAXPS/MINPS return their second operand on unordered
// inputs). The entry distance is therefore in [0, +inf] and never NaN.
#if defined(__AVX2__)
using VF = __m256;
inline VF vset1(float x) { return _mm256_set1_ps(x); }
inline VF vload(const float* p) { return _mm256_load_ps(p); }
inline VF vsub(VF a, VF b) { return _mm256_sub_ps(a, b); }
inline VF vmul(VF a, VF b) { return _mm256_mul_ps(a, b); }
inline VF vmax(VF a, VF b) { return _mm256_max_ps(a, b); }
inline VF vmin(VF a, VF b) { return _mm256_min_ps(a, b); }
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

struct BoxRay8 {
  VF o[3], inv_d[3], scale;
  int near_row[3], far_row[3];
  explicit BoxRay8(const TraceRay& r) : scale(vset1(r.far_scale)) {
    for (int a = 0; a < 3; ++a) {
      o[a] = vset1(r.o[a]);
      inv_d[a] = vset1(r.inv_d[a]);
      near_row[a] = r.near_row[a];
      far_row[a] = r.far_row[a];
    }
  }
};

// Slab test of a node's eight child boxes against (0, tmax); returns the mask of boxes entered and their entry
// distances.
inline unsigned node_test(const Node& n, const BoxRay8& r, VF tmax, VF* t_entry) {
  VF t0 = vset1(0.f), t1 = tmax;
  for (int a = 0; a < 3; ++a) {
    const VF tn = vmul(vsub(vload(n.box[r.near_row[a]]), r.o[a]), r.inv_d[a]);
    const VF tf = vmul(vmul(vsub(vload(n.box[r.far_row[a]]), r.o[a]), r.inv_d[a]), r.scale);
    t0 = vmax(tn, t0);  // tn > t0 ? tn : t0
    t1 = vmin(tf, t1);  // tf < t1 ? tf : t1
  }
  *t_entry = t0;
  return vle_mask(t0, t1);
}

// Per-ray constants of the 4-wide watertight test.
struct TriRay4 {
  const TraceRay& r;
  __m128 ox, oy, oz, sx, sy, sz;
  explicit TriRay4(const TraceRay& tr)
      : r(tr),
        ox(_mm_set1_ps(tr.ox)),
        oy(_mm_set1_ps(tr.oy)),
        oz(_mm_set1_ps(tr.oz)),
        sx(_mm_set1_ps(tr.sx)),
        sy(_mm_set1_ps(tr.sy)),
        sz(_mm_set1_ps(tr.sz)) {}
};

// Results of four triangle tests: t and the barycentrics of p1 and p2 for the lanes that hit.
struct Lanes4 {
  alignas(16) float t[4];
  alignas(16) float b1[4];
  alignas(16) float b2[4];
};

// The watertight test (core/triangle.h) on the four triangles of a packet, lane by lane with the same operations in
// the same order, so t and the barycentrics are bitwise those of intersect_triangle(). Lanes whose float edge
// functions are zero or whose determinant is not finite go to the same double-precision fallback. `valid` is the
// mask of used lanes. Returns the mask of lanes that hit in (0, tmax); fills `out` for them when given (with no
// `out`, it may stop at the first hit).
inline unsigned triangles4(const float (&v)[3][3][4], unsigned valid, const TriRay4& r, float tmax, Lanes4* out) {
  const TraceRay& w = r.r;
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
  const __m128 finite = _mm_cmple_ps(_mm_and_ps(det, abs_mask), _mm_castsi128_ps(_mm_set1_epi32(0x7f7fffff)));
  const __m128 any_zero =
      _mm_or_ps(_mm_or_ps(_mm_cmpeq_ps(e0, zero), _mm_cmpeq_ps(e1, zero)), _mm_cmpeq_ps(e2, zero));
  const unsigned fallback = unsigned(_mm_movemask_ps(any_zero)) | (unsigned(_mm_movemask_ps(finite)) ^ 0xfu);
  const unsigned fb = fallback & valid;

  const __m128 neg = _mm_or_ps(_mm_or_ps(_mm_cmplt_ps(e0, zero), _mm_cmplt_ps(e1, zero)), _mm_cmplt_ps(e2, zero));
  const __m128 pos = _mm_or_ps(_mm_or_ps(_mm_cmpgt_ps(e0, zero), _mm_cmpgt_ps(e1, zero)), _mm_cmpgt_ps(e2, zero));
  unsigned hit = valid & ~fallback & ~unsigned(_mm_movemask_ps(_mm_and_ps(neg, pos)));
  if (!hit && !fb) return 0;

  const __m128 inv_det = _mm_div_ps(_mm_set1_ps(1.f), det);
  const __m128 szaz = _mm_mul_ps(r.sz, az), szbz = _mm_mul_ps(r.sz, bz), szcz = _mm_mul_ps(r.sz, cz);
  const __m128 t = _mm_mul_ps(
      _mm_add_ps(_mm_add_ps(_mm_mul_ps(e0, szaz), _mm_mul_ps(e1, szbz)), _mm_mul_ps(e2, szcz)), inv_det);
  hit &= unsigned(_mm_movemask_ps(_mm_and_ps(_mm_cmpgt_ps(t, zero), _mm_cmplt_ps(t, _mm_set1_ps(tmax)))));
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
    for (unsigned m = fb; m; m &= m - 1) {
      const int k = lowest(m);
      const float sh[9] = {s[0][k], s[1][k], s[2][k], s[3][k], s[4][k], s[5][k], s[6][k], s[7][k], s[8][k]};
      HitRecord h;
      if (triangle_fallback(sh, w.sz, tmax, &h)) {
        hit |= 1u << k;
        if (!out) return hit;
        out->t[k] = h.t;
        out->b1[k] = h.b1;
        out->b2[k] = h.b2;
      }
    }
  }
  return hit;
}

inline unsigned valid_lanes(const uint32_t (&id)[4]) {
  const __m128i ids = _mm_load_si128(reinterpret_cast<const __m128i*>(id));
  return unsigned(_mm_movemask_ps(_mm_castsi128_ps(_mm_cmpeq_epi32(ids, _mm_set1_epi32(-1))))) ^ 0xfu;
}

// Asks for the cache lines a child reference will touch first: a node's four lines or a leaf's first packet.
inline void prefetch_child(uint32_t ref, const Tree& tree) {
  const char* p = (ref & kLeafBit) ? reinterpret_cast<const char*>(tree.packets + (ref & ~kLeafBit))
                                   : reinterpret_cast<const char*>(tree.nodes + ref);
  _mm_prefetch(p, _MM_HINT_T0);
  _mm_prefetch(p + 64, _MM_HINT_T0);
  _mm_prefetch(p + 128, _MM_HINT_T0);
  if (!(ref & kLeafBit)) _mm_prefetch(p + 192, _MM_HINT_T0);
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

// The closest hit. Children are visited nearest first by their sort keys (entry distance, then slot), the others
// pushed farthest first; a popped entry whose entry distance lies beyond the closest hit so far is dropped.
bool intersect(const Tree& tree, const TraceRay& ray, HitRecord* out) {
  const BoxRay8 sr(ray);
  const TriRay4 tr(ray);
  float tmax = ray.tmax;
  HitRecord best{};
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
      const unsigned valid = valid_lanes(pk->id);
      if (id0 < tree.num_triangles) {
        Lanes4 lanes;
        for (unsigned m = triangles4(pk->v, valid, tr, tmax, &lanes); m; m &= m - 1) {
          const int k = lowest(m);
          if (lanes.t[k] < tmax) {  // lanes in order, as a sequential loop would accept them
            tmax = lanes.t[k];
            best = HitRecord{lanes.t[k], lanes.b1[k], lanes.b2[k], k == 0 ? id0 : pk->id[k]};
            found = true;
          }
        }
      } else {
        for (unsigned m = valid; m; m &= m - 1) {
          const int k = lowest(m);
          float th;
          if (sphere_hit(ray, pk->v[0][0][k], pk->v[0][1][k], pk->v[0][2][k], pk->v[1][0][k], tmax, &th)) {
            tmax = th;
            best = HitRecord{th, 0.f, 0.f, k == 0 ? id0 : pk->id[k]};
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
bool occluded(const Tree& tree, const TraceRay& ray) {
  const BoxRay8 sr(ray);
  const TriRay4 tr(ray);
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
      const unsigned valid = valid_lanes(pk->id);
      if ((pk->id[0] & ~kLastPacket) < tree.num_triangles) {
        if (triangles4(pk->v, valid, tr, tmax, nullptr)) return true;
      } else {
        for (unsigned m = valid; m; m &= m - 1) {
          const int k = lowest(m);
          float th;
          if (sphere_hit(ray, pk->v[0][0][k], pk->v[0][1][k], pk->v[0][2][k], pk->v[1][0][k], tmax, &th))
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
