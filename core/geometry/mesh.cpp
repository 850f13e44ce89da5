#include "core/geometry/mesh.h"

#include <cmath>
#include <map>
#include <tuple>
#include <unordered_map>

namespace tessera {

std::vector<Triangle> TriangleMesh::triangles() const {
  std::vector<Triangle> out;
  out.reserve(faces.size());
  for (const auto& f : faces) out.push_back(Triangle{p[f.x], p[f.y], p[f.z]});
  return out;
}

Bounds3 TriangleMesh::bounds() const {
  Bounds3 b;
  for (const auto& v : p) b.extend(v);
  return b;
}

TriangleMesh make_icosphere(const Vec3& center, float radius, int subdivisions) {
  const float t = (1.f + std::sqrt(5.f)) / 2.f;
  std::vector<Vec3d> unit = {{-1, t, 0}, {1, t, 0}, {-1, -t, 0}, {1, -t, 0}, {0, -1, t}, {0, 1, t},
                             {0, -1, -t}, {0, 1, -t}, {t, 0, -1}, {t, 0, 1}, {-t, 0, -1}, {-t, 0, 1}};
  for (auto& v : unit) v = glm::normalize(v);
  std::vector<glm::uvec3> faces = {{0, 11, 5}, {0, 5, 1}, {0, 1, 7}, {0, 7, 10}, {0, 10, 11},
                                   {1, 5, 9}, {5, 11, 4}, {11, 10, 2}, {10, 7, 6}, {7, 1, 8},
                                   {3, 9, 4}, {3, 4, 2}, {3, 2, 6}, {3, 6, 8}, {3, 8, 9},
                                   {4, 9, 5}, {2, 4, 11}, {6, 2, 10}, {8, 6, 7}, {9, 8, 1}};
  for (int s = 0; s < subdivisions; ++s) {
    std::map<std::pair<uint32_t, uint32_t>, uint32_t> mid;
    auto midpoint = [&](uint32_t a, uint32_t b) {
      const auto key = std::minmax(a, b);
      auto it = mid.find(key);
      if (it != mid.end()) return it->second;
      unit.push_back(glm::normalize(unit[a] + unit[b]));
      const uint32_t idx = uint32_t(unit.size() - 1);
      mid.emplace(key, idx);
      return idx;
    };
    std::vector<glm::uvec3> next;
    next.reserve(faces.size() * 4);
    for (const auto& f : faces) {
      const uint32_t a = midpoint(f.x, f.y), b = midpoint(f.y, f.z), c = midpoint(f.z, f.x);
      next.push_back({f.x, a, c});
      next.push_back({f.y, b, a});
      next.push_back({f.z, c, b});
      next.push_back({a, b, c});
    }
    faces.swap(next);
  }
  TriangleMesh m;
  m.p.reserve(unit.size());
  for (const auto& v : unit) m.p.push_back(Vec3(Vec3d(center) + double(radius) * v));
  m.faces = std::move(faces);
  return m;
}

TriangleMesh make_box_grid(const Vec3& lo, const Vec3& hi, int n) {
  TriangleMesh m;
  std::map<std::tuple<int, int, int>, uint32_t> index;
  auto vertex = [&](int i, int j, int k) {
    auto key = std::make_tuple(i, j, k);
    auto it = index.find(key);
    if (it != index.end()) return it->second;
    const Vec3d f(double(i) / n, double(j) / n, double(k) / n);
    m.p.push_back(Vec3(Vec3d(lo) + f * (Vec3d(hi) - Vec3d(lo))));
    const uint32_t idx = uint32_t(m.p.size() - 1);
    index.emplace(key, idx);
    return idx;
  };
  // Each face: fixed axis `a` at grid coordinate `side` (0 or n), grid over the other two axes.
  for (int a = 0; a < 3; ++a) {
    for (int side : {0, n}) {
      const int u = (a + 1) % 3, v = (a + 2) % 3;
      for (int i = 0; i < n; ++i)
        for (int j = 0; j < n; ++j) {
          auto at = [&](int di, int dj) {
            int c[3];
            c[a] = side;
            c[u] = i + di;
            c[v] = j + dj;
            return vertex(c[0], c[1], c[2]);
          };
          const uint32_t q00 = at(0, 0), q10 = at(1, 0), q11 = at(1, 1), q01 = at(0, 1);
          if (side == 0) {
            m.faces.push_back({q00, q11, q10});
            m.faces.push_back({q00, q01, q11});
          } else {
            m.faces.push_back({q00, q10, q11});
            m.faces.push_back({q00, q11, q01});
          }
        }
    }
  }
  return m;
}

TriangleMesh make_needle_cylinder(const Vec3& base_center, float radius, float height, int segments) {
  TriangleMesh m;
  const Vec3d c(base_center);
  for (int ring = 0; ring < 2; ++ring)
    for (int s = 0; s < segments; ++s) {
      const double phi = 2.0 * M_PI * s / segments;
      m.p.push_back(Vec3(c + Vec3d(radius * std::cos(phi), ring * double(height), radius * std::sin(phi))));
    }
  const uint32_t bottom_center = uint32_t(m.p.size());
  m.p.push_back(Vec3(c));
  const uint32_t top_center = uint32_t(m.p.size());
  m.p.push_back(Vec3(c + Vec3d(0, height, 0)));
  const uint32_t S = uint32_t(segments);
  for (uint32_t s = 0; s < S; ++s) {
    const uint32_t b0 = s, b1 = (s + 1) % S, t0 = S + s, t1 = S + (s + 1) % S;
    m.faces.push_back({b0, t0, t1});
    m.faces.push_back({b0, t1, b1});
    m.faces.push_back({bottom_center, b0, b1});
    m.faces.push_back({top_center, t1, t0});
  }
  return m;
}

TriangleMesh make_bumpy_sphere(const Vec3& center, float radius, size_t target_triangles) {
  // A UV sphere with `rings` latitude bands and 2*rings longitude segments has about 4*rings^2 triangles.
  const int rings = std::max(4, int(std::sqrt(double(target_triangles) / 4.0)));
  const int segs = 2 * rings;
  TriangleMesh m;
  auto displaced = [&](double theta, double phi) {
    const Vec3d dir(std::sin(theta) * std::cos(phi), std::cos(theta), std::sin(theta) * std::sin(phi));
    const double bump = 1.0 + 0.05 * std::sin(9 * theta) * std::cos(7 * phi) + 0.02 * std::sin(31 * phi + 5 * theta);
    return Vec3(Vec3d(center) + double(radius) * bump * dir);
  };
  m.p.push_back(displaced(0, 0));  // north pole
  for (int r = 1; r < rings; ++r)
    for (int s = 0; s < segs; ++s) m.p.push_back(displaced(M_PI * r / rings, 2 * M_PI * s / segs));
  m.p.push_back(displaced(M_PI, 0));  // south pole
  const uint32_t south = uint32_t(m.p.size() - 1);
  auto ring_vertex = [&](int r, int s) { return uint32_t(1 + (r - 1) * segs + (s % segs)); };
  for (int s = 0; s < segs; ++s) m.faces.push_back({0, ring_vertex(1, s + 1), ring_vertex(1, s)});
  for (int r = 1; r < rings - 1; ++r)
    for (int s = 0; s < segs; ++s) {
      const uint32_t a = ring_vertex(r, s), b = ring_vertex(r, s + 1), c = ring_vertex(r + 1, s + 1),
                     d = ring_vertex(r + 1, s);
      m.faces.push_back({a, b, c});
      m.faces.push_back({a, c, d});
    }
  for (int s = 0; s < segs; ++s) m.faces.push_back({south, ring_vertex(rings - 1, s), ring_vertex(rings - 1, s + 1)});
  return m;
}

}  // namespace tessera
