// Tessera's BVH against Embree 3 on identical scenes and identical rays.
//
// One run prints, side by side:
//   * single-threaded closest-hit and any-hit throughput (Mrays/s, best of 3) for the Tessera BVH, Embree with
//     default scene flags and Embree with RTC_SCENE_FLAG_ROBUST, on coherent (pinhole camera) and incoherent
//     (random origin, random direction) rays over a ~40-triangle Cornell box and a >= 1M-triangle bumpy sphere;
//   * build times (all TBB threads, best of 3): Bvh::build against rtcCommitScene;
//   * a cross-check: hit/miss agreement and the largest relative difference of t where both hit.
// Embree is used through its public C API only, and only in this benchmark.
//
// Usage: bvh_vs_embree [--quick] [--build-only] [--threads N] [--csv] [--reps N]
//   --quick       ~100k rays per set and a 200k-triangle sphere (smoke test, a few seconds)
//   --build-only  the build table only (no rays traced)
//   --threads N   builds on at most N TBB threads (both libraries build on TBB)
//   --csv         also print the results as CSV after the tables

#include "bench/run_environment.h"
#include "core/geometry/bvh.h"
#include "core/util/math.h"
#include "core/geometry/mesh.h"
#include "core/geometry/ray.h"
#include "core/util/simd_path.h"

#include <embree3/rtcore.h>
#include <tbb/global_control.h>
#include <tbb/info.h>
#include <xmmintrin.h>

#include <algorithm>
#include <atomic>
#include <array>
#include <chrono>
#include <cinttypes>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <limits>
#include <optional>
#include <string>
#include <string_view>
#include <thread>
#include <vector>

namespace {

using namespace tessera;
using Clock = std::chrono::steady_clock;
using tessera::bench::cpu_model;
using tessera::bench::load_average;

// ------------------------------------------------------------------------------------------------------------
// Errors (the run's machine, commit and load come from bench/run_environment.h).

[[noreturn]] void die(const char* what) {
  std::fflush(stdout);
  std::fprintf(stderr, "bvh_vs_embree: %s\n", what);
  std::exit(1);
}

const char* embree_error_name(RTCError code) {
  switch (code) {
    case RTC_ERROR_NONE: return "RTC_ERROR_NONE";
    case RTC_ERROR_UNKNOWN: return "RTC_ERROR_UNKNOWN";
    case RTC_ERROR_INVALID_ARGUMENT: return "RTC_ERROR_INVALID_ARGUMENT";
    case RTC_ERROR_INVALID_OPERATION: return "RTC_ERROR_INVALID_OPERATION";
    case RTC_ERROR_OUT_OF_MEMORY: return "RTC_ERROR_OUT_OF_MEMORY";
    case RTC_ERROR_UNSUPPORTED_CPU: return "RTC_ERROR_UNSUPPORTED_CPU";
    case RTC_ERROR_CANCELLED: return "RTC_ERROR_CANCELLED";
  }
  return "unrecognised RTCError";
}

// Any Embree error ends the run with a non-zero status. The callback may run on a TBB worker thread during a
// build, so it leaves with _Exit (no static destructors racing other threads) after flushing.
void on_embree_error(void* /*user*/, RTCError code, const char* message) {
  std::fflush(stdout);
  std::fprintf(stderr, "bvh_vs_embree: Embree error %s (%d): %s\n", embree_error_name(code), int(code),
               message ? message : "");
  std::fflush(stderr);
  std::_Exit(3);
}

// ------------------------------------------------------------------------------------------------------------
// Scenes.

struct Camera {
  Vec3 eye, look, up;
  float fov_deg;  // vertical (the image is square)
};

struct Scene {
  std::string name;
  TriangleMesh mesh;
  std::vector<Triangle> triangles;  // mesh.triangles(): Tessera's input, in face order (= Embree primID)
  Bounds3 bounds;
  Camera camera;
};

// Two triangles (a, b, c) and (a, c, d) over an existing cyclic quad of vertex indices.
void add_quad(TriangleMesh& m, uint32_t a, uint32_t b, uint32_t c, uint32_t d) {
  m.faces.push_back({a, b, c});
  m.faces.push_back({a, c, d});
}

void add_quad(TriangleMesh& m, const Vec3& a, const Vec3& b, const Vec3& c, const Vec3& d) {
  const auto i = uint32_t(m.p.size());
  m.p.insert(m.p.end(), {a, b, c, d});
  add_quad(m, i, i + 1, i + 2, i + 3);
}

// A closed box standing on y = 0: square footprint of half-size `half` centred at (cx, cz), rotated about y.
void add_rotated_box(TriangleMesh& m, float cx, float cz, float half, float height, float angle_deg) {
  const float a = angle_deg * kPi / 180.f, c = std::cos(a), s = std::sin(a);
  const auto base = uint32_t(m.p.size());
  for (int k = 0; k < 8; ++k) {  // bit 0: +x, bit 1: +z, bit 2: top
    const float x = (k & 1) ? half : -half, z = (k & 2) ? half : -half, y = (k & 4) ? height : 0.f;
    m.p.push_back(Vec3(cx + c * x + s * z, y, cz - s * x + c * z));
  }
  const auto q = [&](uint32_t i0, uint32_t i1, uint32_t i2, uint32_t i3) {
    add_quad(m, base + i0, base + i1, base + i2, base + i3);
  };
  q(0, 1, 3, 2);  // bottom
  q(4, 6, 7, 5);  // top
  q(0, 2, 6, 4);  // -x
  q(1, 5, 7, 3);  // +x
  q(0, 4, 5, 1);  // -z
  q(2, 3, 7, 6);  // +z
}

// Cornell box: open towards +z, walls x,z in [-1,1], y in [0,2]; proportions of the original 555-unit box.
TriangleMesh make_cornell_box() {
  TriangleMesh m;
  add_quad(m, {-1, 0, -1}, {1, 0, -1}, {1, 0, 1}, {-1, 0, 1});   // floor
  add_quad(m, {-1, 2, -1}, {-1, 2, 1}, {1, 2, 1}, {1, 2, -1});   // ceiling
  add_quad(m, {-1, 0, -1}, {-1, 2, -1}, {1, 2, -1}, {1, 0, -1}); // back
  add_quad(m, {-1, 0, -1}, {-1, 0, 1}, {-1, 2, 1}, {-1, 2, -1}); // left
  add_quad(m, {1, 0, -1}, {1, 2, -1}, {1, 2, 1}, {1, 0, 1});     // right
  add_rotated_box(m, 0.33f, 0.37f, 0.297f, 0.595f, -17.f);       // short box, front right
  add_rotated_box(m, -0.33f, -0.27f, 0.297f, 1.19f, 17.f);       // tall box, back left
  add_quad(m, {-0.24f, 1.98f, -0.19f}, {0.24f, 1.98f, -0.19f}, {0.24f, 1.98f, 0.19f},
           {-0.24f, 1.98f, 0.19f});                              // light, just below the ceiling
  return m;
}

Scene cornell_scene() {
  Scene s;
  s.name = "cbox";
  s.mesh = make_cornell_box();
  s.camera = Camera{{0.f, 1.f, 6.8f}, {0.f, 1.f, 0.f}, {0.f, 1.f, 0.f}, 19.5f};
  return s;
}

// make_bumpy_sphere gives "about" the requested count; ask for more until there are at least min_triangles.
Scene bumpy_sphere_scene(size_t min_triangles) {
  Scene s;
  s.name = "sphere";
  size_t target = min_triangles;
  s.mesh = make_bumpy_sphere(Vec3(0.f), 1.f, target);
  while (s.mesh.faces.size() < min_triangles) {
    target += target / 100 + 1;
    s.mesh = make_bumpy_sphere(Vec3(0.f), 1.f, target);
  }
  // From distance 3 the silhouette subtends ~19.5 deg half-angle; a 36 deg fov fills ~88% of the square image.
  s.camera = Camera{{0.f, 0.f, 3.f}, {0.f, 0.f, 0.f}, {0.f, 1.f, 0.f}, 36.f};
  return s;
}

void finish_scene(Scene& s) {
  s.triangles = s.mesh.triangles();
  s.bounds = s.mesh.bounds();
}

// ------------------------------------------------------------------------------------------------------------
// Rays.

// SplitMix64: small, fast, and the same sequence everywhere (unlike std:: distributions).
struct Rng {
  uint64_t state;
  uint64_t next() {
    uint64_t z = (state += 0x9e3779b97f4a7c15ull);
    z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ull;
    z = (z ^ (z >> 27)) * 0x94d049bb133111ebull;
    return z ^ (z >> 31);
  }
  float uniform() { return float(next() >> 40) * 0x1p-24f; }  // [0, 1)
};

// Pinhole camera, res x res pixel centres in row order (top row first), normalised directions, tmax = inf.
std::vector<Ray> camera_rays(const Camera& cam, int res) {
  const Vec3 f = glm::normalize(cam.look - cam.eye);
  const Vec3 r = glm::normalize(glm::cross(f, cam.up));
  const Vec3 u = glm::cross(r, f);
  const float th = std::tan(0.5f * cam.fov_deg * kPi / 180.f);
  std::vector<Ray> rays;
  rays.reserve(size_t(res) * size_t(res));
  for (int y = 0; y < res; ++y)
    for (int x = 0; x < res; ++x) {
      const float sx = (2.f * (float(x) + 0.5f) / float(res) - 1.f) * th;
      const float sy = (1.f - 2.f * (float(y) + 0.5f) / float(res)) * th;
      Ray ray;
      ray.o = cam.eye;
      ray.d = glm::normalize(f + sx * r + sy * u);
      ray.tmax = kInfinity;
      rays.push_back(ray);
    }
  return rays;
}

// Origins uniform in the box, directions uniform on the unit sphere, tmax = inf.
std::vector<Ray> incoherent_rays(const Bounds3& b, size_t n, uint64_t seed) {
  Rng rng{seed};
  std::vector<Ray> rays;
  rays.reserve(n);
  const Vec3 ext = b.hi - b.lo;
  for (size_t i = 0; i < n; ++i) {
    Ray ray;
    ray.o = b.lo + ext * Vec3(rng.uniform(), rng.uniform(), rng.uniform());
    const float z = 1.f - 2.f * rng.uniform();
    const float rad = std::sqrt(std::max(0.f, 1.f - z * z));
    const float phi = 2.f * kPi * rng.uniform();
    ray.d = Vec3(rad * std::cos(phi), rad * std::sin(phi), z);
    ray.tmax = kInfinity;
    rays.push_back(ray);
  }
  return rays;
}

// ------------------------------------------------------------------------------------------------------------
// Embree scenes.

// Geometry creation and buffer filling happen here, outside any timer; only rtcCommitScene is timed.
RTCScene new_embree_scene(RTCDevice device, const TriangleMesh& m, bool robust) {
  RTCScene scene = rtcNewScene(device);
  rtcSetSceneFlags(scene, robust ? RTC_SCENE_FLAG_ROBUST : RTC_SCENE_FLAG_NONE);
  RTCGeometry geom = rtcNewGeometry(device, RTC_GEOMETRY_TYPE_TRIANGLE);
  auto* v = static_cast<float*>(rtcSetNewGeometryBuffer(geom, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3,
                                                        3 * sizeof(float), m.p.size()));
  for (size_t i = 0; i < m.p.size(); ++i) {
    v[3 * i + 0] = m.p[i].x;
    v[3 * i + 1] = m.p[i].y;
    v[3 * i + 2] = m.p[i].z;
  }
  auto* idx = static_cast<unsigned*>(rtcSetNewGeometryBuffer(geom, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3,
                                                             3 * sizeof(unsigned), m.faces.size()));
  for (size_t i = 0; i < m.faces.size(); ++i) {
    idx[3 * i + 0] = m.faces[i].x;
    idx[3 * i + 1] = m.faces[i].y;
    idx[3 * i + 2] = m.faces[i].z;
  }
  rtcCommitGeometry(geom);
  rtcAttachGeometryByID(scene, geom, 0);
  rtcReleaseGeometry(geom);
  return scene;
}

// ------------------------------------------------------------------------------------------------------------
// Query loops. Each writes one result per ray (so the cross-check sees every ray and nothing can be elided)
// and returns a checksum: the sum of hit distances (closest hit) or the number of occluded rays (any hit).

constexpr uint32_t kNoPrim = std::numeric_limits<uint32_t>::max();

struct ClosestResults {
  std::vector<float> t;        // inf on a miss
  std::vector<uint32_t> prim;  // kNoPrim on a miss
  void resize(size_t n) { t.resize(n); prim.resize(n); }
};

double tessera_closest(const Bvh& bvh, const std::vector<Ray>& rays, size_t begin, size_t end, ClosestResults& out) {
  double sum = 0.0;
  for (size_t i = begin; i < end; ++i) {
    const std::optional<Hit> h = bvh.intersect(rays[i]);
    if (h) {
      out.t[i] = h->t;
      out.prim[i] = h->prim;
      sum += h->t;
    } else {
      out.t[i] = kInfinity;
      out.prim[i] = kNoPrim;
    }
  }
  return sum;
}

double tessera_anyhit(const Bvh& bvh, const std::vector<Ray>& rays, size_t begin, size_t end, std::vector<uint8_t>& out) {
  uint64_t count = 0;
  for (size_t i = begin; i < end; ++i) {
    const bool occ = bvh.occluded(rays[i]);
    out[i] = occ;
    count += occ;
  }
  return double(count);
}

// rtcIntersect1 requires a 16-byte aligned RTCRayHit; the type carries RTC_ALIGN(16) members, and the locals
// below are declared alignas(16) as well so the requirement is explicit.
static_assert(alignof(RTCRayHit) >= 16 && alignof(RTCRay) >= 16);

inline void fill_rtc_ray(RTCRay& er, const Ray& r) {
  er.org_x = r.o.x;
  er.org_y = r.o.y;
  er.org_z = r.o.z;
  er.tnear = 0.f;
  er.dir_x = r.d.x;
  er.dir_y = r.d.y;
  er.dir_z = r.d.z;
  er.time = 0.f;
  er.tfar = r.tmax;
  er.mask = 0xFFFFFFFFu;
  er.id = 0;
  er.flags = 0;
}

double embree_closest(RTCScene scene, const std::vector<Ray>& rays, size_t begin, size_t end, ClosestResults& out) {
  RTCIntersectContext ctx;
  rtcInitIntersectContext(&ctx);
  double sum = 0.0;
  for (size_t i = begin; i < end; ++i) {
    alignas(16) RTCRayHit rh;
    fill_rtc_ray(rh.ray, rays[i]);
    rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
    rh.hit.instID[0] = RTC_INVALID_GEOMETRY_ID;
    rtcIntersect1(scene, &ctx, &rh);
    if (rh.hit.geomID != RTC_INVALID_GEOMETRY_ID) {
      out.t[i] = rh.ray.tfar;
      out.prim[i] = rh.hit.primID;
      sum += rh.ray.tfar;
    } else {
      out.t[i] = kInfinity;
      out.prim[i] = kNoPrim;
    }
  }
  return sum;
}

double embree_anyhit(RTCScene scene, const std::vector<Ray>& rays, size_t begin, size_t end, std::vector<uint8_t>& out) {
  RTCIntersectContext ctx;
  rtcInitIntersectContext(&ctx);
  uint64_t count = 0;
  for (size_t i = begin; i < end; ++i) {
    alignas(16) RTCRay er;
    fill_rtc_ray(er, rays[i]);
    rtcOccluded1(scene, &ctx, &er);
    const bool occ = er.tfar < 0.f;  // rtcOccluded1 sets tfar to -inf on a hit
    out[i] = occ;
    count += occ;
  }
  return double(count);
}

// ------------------------------------------------------------------------------------------------------------
// Measurement.

// The implementations, in column order: Tessera on each SimdPath this CPU runs, then Embree default and robust.
struct Impl {
  std::string name;       // column header
  std::string csv_name;   // CSV name
  bool tessera = false;
  SimdPath path = SimdPath::kSse2;  // Tessera only
  int embree = -1;        // 0 default, 1 robust
};

std::vector<Impl> make_impls() {
  std::vector<Impl> v;
  for (SimdPath p : supported_simd_paths()) {
    const std::string n(kSimdPathNames[size_t(p)]);
    v.push_back({"T-" + n, "tessera_" + n, true, p, -1});
  }
  v.push_back({"Emb-def", "embree_default", false, SimdPath::kSse2, 0});
  v.push_back({"Emb-rob", "embree_robust", false, SimdPath::kSse2, 1});
  return v;
}

const std::vector<Impl>& impls() {
  static const std::vector<Impl> v = make_impls();
  return v;
}
int num_impls() { return int(impls().size()); }
int embree_impl(int e) { return num_impls() - 2 + e; }
// Tessera's default path (best_simd_path()): the last Tessera column.
int tessera_default_impl() { return num_impls() - 3; }

double seconds_since(Clock::time_point t0) { return std::chrono::duration<double>(Clock::now() - t0).count(); }

// Build time of Tessera (one build serves every SimdPath) and of the two Embree scenes, and their sizes.
struct BuildRow {
  std::string scene;
  size_t triangles = 0;
  std::array<double, 3> best_s{};    // wall time: Tessera, Embree default, Embree robust
  std::array<double, 3> best_cpu{};  // CPU time of all the process's threads, same order
  std::array<double, 3> bytes{};     // acceleration structure bytes, same order
  BvhStats stats;
};

// Embree's allocations as its device memory monitor reports them (bytes allocated minus bytes freed).
std::atomic<int64_t> g_embree_bytes{0};
bool on_embree_memory(void* /*user*/, ssize_t bytes, bool /*post*/) {
  g_embree_bytes.fetch_add(int64_t(bytes), std::memory_order_relaxed);
  return true;
}

struct Built {
  Bvh bvh;
  std::array<RTCScene, 2> embree{};  // default, robust
};

// CPU time of all the process's threads in seconds (user and system: page faults count).
double process_seconds() {
  timespec ts;
  clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts);
  return double(ts.tv_sec) + 1e-9 * double(ts.tv_nsec);
}

// CPU time of the calling thread in seconds: time the thread spent descheduled (other processes share the machine)
// does not count.
double thread_seconds() {
  timespec ts;
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
  return double(ts.tv_sec) + 1e-9 * double(ts.tv_nsec);
}

// Builds everything reps times (order rotated per repetition) and keeps the last of each; each builder's previous
// structure is freed before it builds again. Embree's bytes are the net allocation of rtcCommitScene (the
// geometry's buffers are made before and not counted).
Built build_all(RTCDevice device, const Scene& s, int reps, BuildRow& row) {
  Built out;
  row.scene = s.name;
  row.triangles = s.triangles.size();
  row.best_s.fill(std::numeric_limits<double>::infinity());
  row.best_cpu.fill(std::numeric_limits<double>::infinity());
  for (int rep = 0; rep < reps; ++rep) {
    for (int k = 0; k < 3; ++k) {
      const int which = (rep + k) % 3;  // 0 Tessera, 1 Embree default, 2 Embree robust
      if (which == 0) {
        out.bvh = Bvh{};  // the previous tree is freed first, as the previous Embree scene is below
        const double c0 = process_seconds();
        const auto t0 = Clock::now();
        out.bvh = Bvh::build(s.triangles, {}, BvhOptions{});
        row.best_s[0] = std::min(row.best_s[0], seconds_since(t0));
        row.best_cpu[0] = std::min(row.best_cpu[0], process_seconds() - c0);
        row.bytes[0] = double(out.bvh.memory_bytes());
      } else {
        const int e = which - 1;
        if (out.embree[e]) rtcReleaseScene(out.embree[e]);
        out.embree[e] = nullptr;
        RTCScene scene = new_embree_scene(device, s.mesh, e == 1);
        const int64_t before = g_embree_bytes.load();
        const double c0 = process_seconds();
        const auto t0 = Clock::now();
        rtcCommitScene(scene);
        row.best_s[which] = std::min(row.best_s[which], seconds_since(t0));
        row.best_cpu[which] = std::min(row.best_cpu[which], process_seconds() - c0);
        row.bytes[which] = double(g_embree_bytes.load() - before);
        out.embree[e] = scene;
      }
    }
  }
  row.stats = out.bvh.stats();
  return out;
}

struct ThroughputRow {
  std::string scene, rays, query;
  size_t n = 0;
  std::vector<double> best_s = std::vector<double>(size_t(num_impls()), std::numeric_limits<double>::infinity());
  std::vector<double> checksum = std::vector<double>(size_t(num_impls()), 0.0);
  double mrays(int impl) const { return double(n) / best_s[impl] / 1e6; }
};

struct CheckRow {
  std::string scene, rays;
  size_t n = 0;
  double ours_hit_frac = 0;                // fraction of rays Tessera's closest-hit query hits
  std::array<double, 2> closest_agree{};   // hit/miss agreement, closest hit, vs default / robust
  std::array<double, 2> max_rel_dt{};      // max |t_ours - t_embree| / t_embree over rays both hit
  std::array<double, 2> max_abs_dt{};      // max |t_ours - t_embree| over rays both hit (scene units; |d| = 1)
  std::array<size_t, 2> far{};            // rays both hit with |dt| > kFarDt: a different surface was hit
  std::array<double, 2> prim_match{};      // fraction of both-hit rays reporting the same triangle
  std::array<double, 2> anyhit_agree{};    // occluded/not agreement, any hit, vs default / robust
  double ours_self = 0;                    // Tessera: occluded() == intersect().has_value()
  double paths_agree = 1;                  // rays where every SimdPath gave bitwise the same t, prim, occlusion
};

// Scene units (both scenes span ~2): a t difference this large is not rounding but a different surface, e.g. a
// ray that slipped through a crack between adjacent triangles and hit the far side of a closed mesh.
constexpr double kFarDt = 1e-3;

CheckRow cross_check(const std::string& scene, const std::string& rays_name, const std::vector<ClosestResults>& c,
                     const std::vector<std::vector<uint8_t>>& a) {
  CheckRow row;
  row.scene = scene;
  row.rays = rays_name;
  const int kTessera = tessera_default_impl();
  const size_t n = c[kTessera].t.size();
  size_t paths_same = 0;
  for (size_t i = 0; i < n; ++i) {
    bool same = true;
    for (int k = 1; k <= kTessera; ++k)
      same = same && std::memcmp(&c[k].t[i], &c[0].t[i], sizeof(float)) == 0 && c[k].prim[i] == c[0].prim[i] &&
             a[k][i] == a[0][i];
    paths_same += same;
  }
  row.paths_agree = double(paths_same) / double(n);
  row.n = n;
  size_t ours_hits = 0, self = 0;
  for (size_t i = 0; i < n; ++i) {
    const bool h = c[kTessera].prim[i] != kNoPrim;
    ours_hits += h;
    self += (bool(a[kTessera][i]) == h);
  }
  row.ours_hit_frac = double(ours_hits) / double(n);
  row.ours_self = double(self) / double(n);
  for (int e = 0; e < 2; ++e) {
    const int impl = embree_impl(e);
    size_t agree = 0, both = 0, same_prim = 0, any_agree = 0, far = 0;
    double max_rel = 0.0, max_abs = 0.0;
    for (size_t i = 0; i < n; ++i) {
      const bool ho = c[kTessera].prim[i] != kNoPrim, he = c[impl].prim[i] != kNoPrim;
      agree += (ho == he);
      any_agree += (a[kTessera][i] == a[impl][i]);
      if (ho && he) {
        ++both;
        same_prim += (c[kTessera].prim[i] == c[impl].prim[i]);
        const double te = c[impl].t[i], to = c[kTessera].t[i];
        const double rel = std::abs(to - te) / std::max(std::abs(te), 1e-30);
        max_rel = std::max(max_rel, rel);
        max_abs = std::max(max_abs, std::abs(to - te));
        far += std::abs(to - te) > kFarDt;
      }
    }
    row.closest_agree[e] = double(agree) / double(n);
    row.anyhit_agree[e] = double(any_agree) / double(n);
    row.max_rel_dt[e] = max_rel;
    row.max_abs_dt[e] = max_abs;
    row.far[e] = far;
    row.prim_match[e] = both ? double(same_prim) / double(both) : 1.0;
  }
  return row;
}

// Runs closest and any hit for every implementation on one thread (this one). The rays are cut into chunks of
// kChunk; each repetition runs every chunk on every implementation, in an order rotated per chunk and repetition,
// and an implementation's time is the sum over chunks of its best time for the chunk (thread CPU time), so
// interference from other processes is filtered per chunk rather than per run.
void measure(const Scene& s, Built& b, const std::string& rays_name, const std::vector<Ray>& rays, int reps,
             std::vector<ThroughputRow>& rows, std::vector<CheckRow>& checks) {
  constexpr size_t kChunk = 65536;
  ThroughputRow closest{s.name, rays_name, "closest", rays.size()};
  ThroughputRow anyhit{s.name, rays_name, "any-hit", rays.size()};
  const int ni = num_impls();
  std::vector<ClosestResults> cres(static_cast<size_t>(ni));
  std::vector<std::vector<uint8_t>> ares(static_cast<size_t>(ni));
  for (int i = 0; i < ni; ++i) {
    cres[i].resize(rays.size());
    ares[i].resize(rays.size());
  }
  const size_t chunks = (rays.size() + kChunk - 1) / kChunk;
  const double inf = std::numeric_limits<double>::infinity();
  std::vector<double> best_c(chunks * size_t(ni), inf), best_a(chunks * size_t(ni), inf);
  std::vector<double> sum_c(chunks * size_t(ni), 0.0), sum_a(chunks * size_t(ni), 0.0);
  for (int rep = 0; rep < reps; ++rep) {
    for (size_t c = 0; c < chunks; ++c) {
      const size_t begin = c * kChunk, end = std::min(rays.size(), begin + kChunk);
      for (int k = 0; k < ni; ++k) {
        const int impl = int((size_t(rep) + c + size_t(k)) % size_t(ni));
        const Impl& im = impls()[size_t(impl)];
        if (im.tessera) b.bvh.set_simd_path(im.path);
        const size_t slot = c * size_t(ni) + size_t(impl);
        double t0 = thread_seconds();
        sum_c[slot] = im.tessera ? tessera_closest(b.bvh, rays, begin, end, cres[impl])
                                 : embree_closest(b.embree[im.embree], rays, begin, end, cres[impl]);
        best_c[slot] = std::min(best_c[slot], thread_seconds() - t0);
        t0 = thread_seconds();
        sum_a[slot] = im.tessera ? tessera_anyhit(b.bvh, rays, begin, end, ares[impl])
                                 : embree_anyhit(b.embree[im.embree], rays, begin, end, ares[impl]);
        best_a[slot] = std::min(best_a[slot], thread_seconds() - t0);
      }
    }
  }
  for (int i = 0; i < ni; ++i) {
    closest.best_s[i] = anyhit.best_s[i] = 0.0;
    for (size_t c = 0; c < chunks; ++c) {
      const size_t slot = c * size_t(ni) + size_t(i);
      closest.best_s[i] += best_c[slot];
      anyhit.best_s[i] += best_a[slot];
      closest.checksum[i] += sum_c[slot];
      anyhit.checksum[i] += sum_a[slot];
    }
  }
  b.bvh.set_simd_path(best_simd_path());
  rows.push_back(closest);
  rows.push_back(anyhit);
  checks.push_back(cross_check(s.name, rays_name, cres, ares));
}

// ------------------------------------------------------------------------------------------------------------

void print_usage(std::FILE* f) {
  std::fputs("usage: bvh_vs_embree [--quick] [--build-only] [--threads N] [--csv] [--reps N]\n"
             "  --quick       ~100k rays per set and a 200k-triangle sphere (smoke test)\n"
             "  --build-only  builds only: the build table, no traversal or cross-check\n"
             "  --threads N   builds on at most N TBB threads (default: all; both libraries build on TBB)\n"
             "  --reps N      repetitions: each figure is the best of N (default 5)\n"
             "  --csv         also print the results as CSV after the tables\n",
             f);
}

}  // namespace

int main(int argc, char** argv) {
  bool quick = false, csv = false, build_only = false;
  int reps = 5;
  int threads = 0;  // 0: TBB's default
  for (int i = 1; i < argc; ++i) {
    const std::string_view a = argv[i];
    if (a == "--quick") {
      quick = true;
    } else if (a == "--build-only") {
      build_only = true;
    } else if (a == "--csv") {
      csv = true;
    } else if (a == "--reps" && i + 1 < argc) {
      reps = std::atoi(argv[++i]);
      if (reps < 1 || reps > 1000) {
        std::fprintf(stderr, "bvh_vs_embree: --reps wants a count from 1 to 1000\n");
        return 2;
      }
    } else if (a == "--threads" && i + 1 < argc) {
      threads = std::atoi(argv[++i]);
      if (threads < 1 || threads > 1024) {
        std::fprintf(stderr, "bvh_vs_embree: --threads wants a count from 1 to 1024\n");
        return 2;
      }
    } else if (a == "--help" || a == "-h") {
      print_usage(stdout);
      return 0;
    } else {
      std::fprintf(stderr, "bvh_vs_embree: unknown argument '%s'\n", argv[i]);
      print_usage(stderr);
      return 2;
    }
  }
  const auto t_start = Clock::now();
  std::optional<tbb::global_control> thread_limit;
  if (threads > 0) thread_limit.emplace(tbb::global_control::max_allowed_parallelism, size_t(threads));
  const int build_threads = int(tbb::global_control::active_value(tbb::global_control::max_allowed_parallelism));

  const int res = quick ? 320 : 1024;                         // camera: res x res rays
  const size_t n_incoherent = size_t(res) * size_t(res);      // same count as the camera set
  const size_t sphere_triangles = quick ? 200'000 : 1'000'000;  // minimum

  RTCDevice device = rtcNewDevice(nullptr);  // default config: all hardware threads
  if (!device) {
    std::fprintf(stderr, "bvh_vs_embree: rtcNewDevice failed: %s\n", embree_error_name(rtcGetDeviceError(nullptr)));
    return 3;
  }
  rtcSetDeviceErrorFunction(device, on_embree_error, nullptr);
  rtcSetDeviceMemoryMonitorFunction(device, on_embree_memory, nullptr);
  const ssize_t tasking = rtcGetDeviceProperty(device, RTC_DEVICE_PROPERTY_TASKING_SYSTEM);
  const char* tasking_name = tasking == 0 ? "internal" : tasking == 1 ? "TBB" : tasking == 2 ? "PPL" : "unknown";

  std::printf("bvh_vs_embree: Tessera BVH vs Embree, same scenes, same rays\n");
  std::printf("commit:  %s\n", tessera::bench::commit_description(TESSERA_SOURCE_DIR, TESSERA_CONFIGURE_COMMIT).c_str());
  std::printf("machine: %s, nproc %u, TBB default concurrency %d\n", cpu_model().c_str(),
              std::thread::hardware_concurrency(), tbb::info::default_concurrency());
  std::printf("build:   %s, TESSERA_NATIVE=%s (Tessera compiled for %s, its traversal kernels for SSE2, AVX2 and\n"
              "         AVX-512 in separate files, chosen at run time; Embree dispatches to the best ISA at run time)\n",
              TESSERA_BUILD_TYPE, TESSERA_NATIVE_BUILD ? "ON" : "OFF",
              TESSERA_NATIVE_BUILD ? "-march=native" : "baseline x86-64 (SSE2)");
  std::string paths;
  for (const Impl& im : impls())
    if (im.tessera) paths += (paths.empty() ? "" : ", ") + im.name;
  std::printf("paths:   %s (this CPU's; default %s)\n", paths.c_str(), kSimdPathNames[size_t(best_simd_path())].data());
  std::printf("load:    %s (1, 5, 15 min load average at the start; other processes share the machine)\n",
              load_average().c_str());
  const unsigned csr = _mm_getcsr();
  std::printf("mxcsr:   FTZ %s, DAZ %s (left at the process default; both libraries trace under the same mode)\n",
              (csr & 0x8000u) ? "on" : "off", (csr & 0x0040u) ? "on" : "off");
  std::printf("embree:  %" PRId64 ".%" PRId64 ".%" PRId64 ", tasking system %s (rtcCommitScene builds on TBB worker threads)\n",
              int64_t(rtcGetDeviceProperty(device, RTC_DEVICE_PROPERTY_VERSION_MAJOR)),
              int64_t(rtcGetDeviceProperty(device, RTC_DEVICE_PROPERTY_VERSION_MINOR)),
              int64_t(rtcGetDeviceProperty(device, RTC_DEVICE_PROPERTY_VERSION_PATCH)), tasking_name);

  std::vector<Scene> scenes;
  scenes.push_back(cornell_scene());
  scenes.push_back(bumpy_sphere_scene(sphere_triangles));
  for (auto& s : scenes) finish_scene(s);

  std::printf("mode:    %s%s: %d x %d camera rays and %zu incoherent rays per scene; sphere %zu triangles; best of %d\n\n",
              quick ? "--quick" : "full", build_only ? ", --build-only (no rays traced)" : "", res, res, n_incoherent, scenes[1].triangles.size(), reps);
  std::fflush(stdout);

  std::vector<BuildRow> builds;
  std::vector<ThroughputRow> rows;
  std::vector<CheckRow> checks;
  uint64_t seed = 0x7e55e7a2024ull;
  for (const Scene& s : scenes) {
    BuildRow br;
    Built b = build_all(device, s, reps, br);
    builds.push_back(br);
    if (build_only) {
      for (RTCScene e : b.embree) rtcReleaseScene(e);
      continue;
    }
    measure(s, b, "coherent", camera_rays(s.camera, res), reps, rows, checks);
    measure(s, b, "incoherent", incoherent_rays(s.bounds, n_incoherent, seed++), reps, rows, checks);
    for (RTCScene e : b.embree) rtcReleaseScene(e);
  }

  // ---- Tables.
  const int nt = tessera_default_impl() + 1;  // Tessera columns
  const int def = embree_impl(0), rob = embree_impl(1);
  if (!build_only) {
    std::printf("Traversal: single thread, Mrays/s from thread CPU time, per 65536-ray chunk best of %d, summed over chunks.\n"
                "Tessera on each SIMD path (T-...), Embree default and robust. ratio = Tessera path / Embree default\n"
                "(1.00 = parity, < 1 = Tessera slower); last column: Tessera's default path / Embree robust\n",
                reps);
    std::printf("%-7s %-10s %-8s %8s |", "scene", "rays", "query", "n");
    for (int i = 0; i < num_impls(); ++i) std::printf(" %8s", impls()[size_t(i)].name.c_str());
    std::printf(" |");
    for (int i = 0; i < nt; ++i) std::printf(" %8s", (impls()[size_t(i)].name.substr(2) + "/def").c_str());
    std::printf(" %8s\n", "dflt/rob");
    const size_t width = size_t(40 + 9 * num_impls() + 2 + 9 * (nt + 1));
    std::printf("%s\n", std::string(width, '-').c_str());
    for (const auto& r : rows) {
      std::printf("%-7s %-10s %-8s %8zu |", r.scene.c_str(), r.rays.c_str(), r.query.c_str(), r.n);
      for (int i = 0; i < num_impls(); ++i) std::printf(" %8.2f", r.mrays(i));
      std::printf(" |");
      for (int i = 0; i < nt; ++i) std::printf(" %8.2f", r.mrays(i) / r.mrays(def));
      std::printf(" %8.2f\n", r.mrays(nt - 1) / r.mrays(rob));
    }
  }

  std::printf("\nBuild: all %d TBB threads, ms, best of %d (Tessera: Bvh::build, one tree for every path; Embree: rtcCommitScene only).\n"
              "wall: elapsed time; cpu: CPU time of all the process's threads during the build (less sensitive to other\n"
              "processes than wall time on a shared machine). time ratio = Tessera / Embree (> 1 = Tessera slower).\n"
              "B/tri: bytes of the acceleration structure per triangle\n"
              "(Tessera: Bvh::memory_bytes(), nodes and leaf packets; Embree: net bytes rtcCommitScene allocated, from the\n"
              "device memory monitor)\n",
              build_threads, reps);
  std::printf("%-7s %9s %-4s | %9s %9s %9s | %8s %8s | %8s %8s %8s | %s\n", "scene", "triangles", "time", "Tessera",
              "Emb-def", "Emb-rob", "ours/def", "ours/rob", "B/tri T", "B/tri def", "B/tri rob",
              "Tessera tree: nodes, depth, SAH cost");
  std::printf("%s\n", std::string(145, '-').c_str());
  for (const auto& b : builds) {
    const double tri = double(std::max<size_t>(b.triangles, 1));
    std::printf("%-7s %9zu %-4s | %9.3f %9.3f %9.3f | %8.2f %8.2f | %8.1f %8.1f %8.1f | %zu, %d, %.2f\n",
                b.scene.c_str(), b.triangles, "wall", b.best_s[0] * 1e3, b.best_s[1] * 1e3, b.best_s[2] * 1e3,
                b.best_s[0] / b.best_s[1], b.best_s[0] / b.best_s[2], b.bytes[0] / tri, b.bytes[1] / tri,
                b.bytes[2] / tri, b.stats.nodes, b.stats.max_depth, b.stats.sah_cost);
    std::printf("%-7s %9s %-4s | %9.3f %9.3f %9.3f | %8.2f %8.2f |\n", "", "", "cpu", b.best_cpu[0] * 1e3,
                b.best_cpu[1] * 1e3, b.best_cpu[2] * 1e3, b.best_cpu[0] / b.best_cpu[1], b.best_cpu[0] / b.best_cpu[2]);
  }

  if (!build_only) {
    std::printf("\nCross-check, Tessera (default path) vs Embree default / robust (same rays; reported, not asserted)\n");
    std::printf("%-7s %-10s %6s | %-17s %-17s %-17s %-11s %-15s | %-17s | %-8s | %s\n", "scene", "rays", "hit%",
                "closest agree%", "max rel |dt|", "max abs |dt|", "far", "same prim%", "any-hit agree%", "self%",
                "paths same%");
    std::printf("%s\n", std::string(156, '-').c_str());
    for (const auto& c : checks) {
      std::printf("%-7s %-10s %6.2f | %8.4f/%-8.4f %8.2e/%-8.2e %8.2e/%-8.2e %5zu/%-5zu %7.3f/%-7.3f | %8.4f/%-8.4f | %8.4f | %.4f\n",
                  c.scene.c_str(), c.rays.c_str(), 100 * c.ours_hit_frac, 100 * c.closest_agree[0],
                  100 * c.closest_agree[1], c.max_rel_dt[0], c.max_rel_dt[1], c.max_abs_dt[0], c.max_abs_dt[1],
                  c.far[0], c.far[1], 100 * c.prim_match[0], 100 * c.prim_match[1], 100 * c.anyhit_agree[0],
                  100 * c.anyhit_agree[1], 100 * c.ours_self, 100 * c.paths_agree);
    }
    std::printf("(x/y = vs Embree default / robust. hit%%: Tessera closest-hit hit rate. same prim%%: of rays both hit.\n"
                " far: rays both hit whose t differ by more than %g, i.e. different surfaces were hit (on a closed mesh:\n"
                " one ray slipped through a crack between triangles and hit the far side).\n"
                " self%%: Tessera occluded() agrees with intersect() hit/miss. A large relative |dt| with a tiny absolute |dt|\n"
                " means a hit very near the ray origin, where ~1e-7 of rounding in t is a large fraction of t.\n"
                " paths same%%: rays on which every Tessera SIMD path gave bitwise the same t, primitive and occlusion.)\n",
                kFarDt);

    std::printf("\nChecksums (closest: sum of hit t; any-hit: occluded count), in column order\n");
    for (const auto& r : rows) {
      std::printf("%-7s %-10s %-8s", r.scene.c_str(), r.rays.c_str(), r.query.c_str());
      for (int i = 0; i < num_impls(); ++i) std::printf("%s%.6e", i ? " / " : " ", r.checksum[i]);
      std::printf("\n");
    }
  }

  if (csv) {
    std::printf("\n# CSV\n");
    std::printf("section,scene,rays,query,n,impl,seconds,mrays_per_s,checksum\n");
    for (const auto& r : rows)
      for (int i = 0; i < num_impls(); ++i)
        std::printf("traversal,%s,%s,%s,%zu,%s,%.6f,%.4f,%.9e\n", r.scene.c_str(), r.rays.c_str(), r.query.c_str(),
                    r.n, impls()[size_t(i)].csv_name.c_str(), r.best_s[i], r.mrays(i), r.checksum[i]);
    std::printf("section,scene,triangles,impl,seconds,cpu_seconds,bytes\n");
    const char* build_names[3] = {"tessera", "embree_default", "embree_robust"};
    for (const auto& b : builds)
      for (int i = 0; i < 3; ++i)
        std::printf("build,%s,%zu,%s,%.6f,%.6f,%.0f\n", b.scene.c_str(), b.triangles, build_names[i], b.best_s[i],
                    b.best_cpu[i], b.bytes[i]);
    std::printf("section,scene,rays,n,embree,ours_hit_frac,closest_agree,max_rel_dt,max_abs_dt,far,prim_match,anyhit_agree,paths_agree\n");
    for (const auto& c : checks)
      for (int e = 0; e < 2; ++e)
        std::printf("check,%s,%s,%zu,%s,%.6f,%.6f,%.3e,%.3e,%zu,%.6f,%.6f,%.6f\n", c.scene.c_str(), c.rays.c_str(),
                    c.n, build_names[e + 1], c.ours_hit_frac, c.closest_agree[e], c.max_rel_dt[e], c.max_abs_dt[e],
                    c.far[e], c.prim_match[e], c.anyhit_agree[e], c.paths_agree);
  }

  std::printf("\nload average at the end: %s\n", load_average().c_str());
  std::printf("\ntotal wall time %.1f s\n", seconds_since(t_start));
  rtcReleaseDevice(device);
  if (std::fflush(stdout) != 0) die("writing stdout failed");
  return 0;
}
