// Indexed triangle meshes and the procedural meshes used by tests, benchmarks and scene generators.
#pragma once

#include "core/geometry/bounds.h"
#include "core/util/math.h"
#include "core/geometry/triangle.h"

#include <cstdint>
#include <vector>

namespace tessera {

/// An indexed triangle mesh; normals and uvs are optional (empty or one per position).
struct TriangleMesh {
  std::vector<Vec3> p;             ///< Positions.
  std::vector<Vec3> n;             ///< Per-vertex shading normals (optional).
  std::vector<Vec2> uv;            ///< Per-vertex texture coordinates (optional).
  std::vector<glm::uvec3> faces;   ///< Vertex indices of each triangle.

  /// The triangles as vertex triples, in face order.
  std::vector<Triangle> triangles() const;
  /// Bounds of all positions.
  Bounds3 bounds() const;
};

/// A closed icosphere of the given radius: 20 * 4^subdivisions triangles, shared vertices bitwise identical.
TriangleMesh make_icosphere(const Vec3& center, float radius, int subdivisions);

/// A closed axis-aligned box whose faces are n x n grids (12 n^2 triangles); shared edges use identical vertices.
TriangleMesh make_box_grid(const Vec3& lo, const Vec3& hi, int n);

/// A closed cylinder made of needles: `segments` thin side quads of height h and two fans of slivers (4*segments
/// triangles). The triangles' aspect ratios reach thousands to one.
TriangleMesh make_needle_cylinder(const Vec3& base_center, float radius, float height, int segments);

/// A closed, bumpy sphere of about `target_triangles` triangles (a UV sphere with a radial displacement), for
/// benchmarks that need a large, non-trivial mesh.
TriangleMesh make_bumpy_sphere(const Vec3& center, float radius, size_t target_triangles);

}  // namespace tessera
