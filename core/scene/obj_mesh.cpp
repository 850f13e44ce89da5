#include "core/scene/obj_mesh.h"

#include "core/scene/obj_limits.h"
#include "core/util/file_io.h"

#include <tiny_obj_loader.h>

#include <limits>

namespace tessera {

namespace {

uint64_t saturating_product(uint64_t a, uint64_t b) {
  return b != 0 && a > std::numeric_limits<uint64_t>::max() / b ? std::numeric_limits<uint64_t>::max() : a * b;
}

}  // namespace

struct ParsedObj {
  tinyobj::attrib_t attrib;
  std::vector<tinyobj::shape_t> shapes;
};

std::shared_ptr<const ParsedObj> ObjParseCache::find(const std::filesystem::path& file) const {
  std::lock_guard lock(mu_);
  const auto it = parsed_.find(file);
  return it == parsed_.end() ? nullptr : it->second;
}

void ObjParseCache::keep(const std::filesystem::path& file, std::shared_ptr<const ParsedObj> parsed) {
  std::lock_guard lock(mu_);
  parsed_[file] = std::move(parsed);
}

namespace {

// Reads and parses `file` within the options' asset limits.
std::shared_ptr<const ParsedObj> parse_obj(const std::filesystem::path& file, const std::string& label,
                                           SceneJson& ctx, const std::string& path) {
  // Bounded before tinyobjloader allocates for what the file declares: its size before it is read, then what its
  // lines declare (core/scene/obj_limits.h).
  const uint64_t max_triangles = ctx.opt.asset_limits.max_triangles;
  const auto too_large = [&](uint64_t n, const char* what, uint64_t limit, const std::string& rule) {
    if (n > limit)
      ctx.fail(path, label + ": mesh too large: " + std::to_string(n) + " " + what + " is over the limit of " +
                         std::to_string(limit) + " (" + rule + ")");
  };
  std::error_code size_error;
  const uintmax_t bytes = std::filesystem::file_size(file, size_error);
  if (!size_error)
    too_large(bytes, "bytes", saturating_product(max_triangles, kObjBytesPerTriangle),
              std::to_string(kObjBytesPerTriangle) + " bytes per triangle of --max-mesh-triangles");
  std::string text;
  try {
    text = read_file_bytes(file);
  } catch (const FileError& e) {
    ctx.fail(path, e.what());
  }
  // OBJ is text; tinyobjloader skips lines it does not know, so a binary file (an EXR named .obj, say) would load
  // as an empty mesh with only a warning.
  if (const size_t nul = text.find('\0'); nul != std::string::npos)
    ctx.fail(path, label + ": not a valid OBJ: binary data (a NUL byte at offset " + std::to_string(nul) + ")");
  const ObjCounts counts = count_obj(text);
  const uint64_t max_vertices = saturating_product(max_triangles, kObjVerticesPerTriangle);
  const std::string per_triangle = std::to_string(kObjVerticesPerTriangle) + " per triangle of --max-mesh-triangles";
  too_large(counts.triangles, "triangles", max_triangles, "--max-mesh-triangles");
  too_large(counts.positions, "vertex positions", max_vertices, per_triangle);
  too_large(counts.normals, "normals", max_vertices, per_triangle);
  too_large(counts.texcoords, "texture coordinates", max_vertices, per_triangle);
  tinyobj::ObjReaderConfig cfg;
  cfg.triangulate = true;
  cfg.vertex_color = false;
  tinyobj::ObjReader reader;
  // Parsed from memory with an empty material library: an OBJ's mtllib can never make us read other files.
  if (!reader.ParseFromString(text, "", cfg)) ctx.fail(path, label + ": not a valid OBJ: " + reader.Error());
  auto parsed = std::make_shared<ParsedObj>();
  parsed->attrib = reader.GetAttrib();
  parsed->shapes = reader.GetShapes();
  return parsed;
}

}  // namespace

ObjMesh load_obj(const std::filesystem::path& file, const std::string& label, const glm::dmat4& xf, const glm::dvec3& translate,
                 const CameraFrame& frame, SceneJson& ctx, const std::string& path) {
  ObjParseCache* const cache = ctx.opt.obj_cache;
  std::shared_ptr<const ParsedObj> parsed = cache ? cache->find(file) : nullptr;
  if (!parsed) {
    parsed = parse_obj(file, label, ctx, path);
    if (cache) cache->keep(file, parsed);
  }
  const auto& attrib = parsed->attrib;
  const size_t nv = attrib.vertices.size() / 3, nn = attrib.normals.size() / 3, nt = attrib.texcoords.size() / 2;
  const glm::mat3 nxf = glm::transpose(glm::inverse(glm::mat3(glm::mat4(xf))));
  ObjMesh m;
  size_t degenerate = 0, face_no = 0;
  for (const auto& shape : parsed->shapes) {
    const auto& idx = shape.mesh.indices;
    if (idx.size() % 3 != 0) ctx.fail(path, label + ": face data is not triangulated");
    for (size_t f = 0; f + 2 < idx.size(); f += 3, ++face_no) {
      Vec3 p[3], n[3];
      Vec2 uv[3];
      bool has_n = true, has_uv = true;
      for (int k = 0; k < 3; ++k) {
        const auto& ix = idx[f + size_t(k)];
        if (ix.vertex_index < 0 || size_t(ix.vertex_index) >= nv)
          ctx.fail(path, label + ": triangle " + std::to_string(face_no + 1) + " refers to vertex " +
                             std::to_string(ix.vertex_index + 1) + " but the file has " + std::to_string(nv));
        const float* v = &attrib.vertices[3 * size_t(ix.vertex_index)];
        const glm::dvec4 w = xf * glm::dvec4(v[0], v[1], v[2], 1.0);
        p[k] = frame.local(glm::dvec3(w) / (w.w != 0.0 ? w.w : 1.0) + translate);
        if (!is_finite(p[k])) ctx.fail(path, label + ": vertex " + std::to_string(ix.vertex_index + 1) + " is not finite");
        if (ix.normal_index >= 0) {
          if (size_t(ix.normal_index) >= nn) ctx.fail(path, label + ": triangle " + std::to_string(face_no + 1) + " refers to normal " + std::to_string(ix.normal_index + 1) + " but the file has " + std::to_string(nn));
          const float* q = &attrib.normals[3 * size_t(ix.normal_index)];
          n[k] = nxf * Vec3(q[0], q[1], q[2]);
        } else {
          has_n = false;
        }
        if (ix.texcoord_index >= 0) {
          if (size_t(ix.texcoord_index) >= nt) ctx.fail(path, label + ": triangle " + std::to_string(face_no + 1) + " refers to texture coordinate " + std::to_string(ix.texcoord_index + 1) + " but the file has " + std::to_string(nt));
          const float* q = &attrib.texcoords[2 * size_t(ix.texcoord_index)];
          uv[k] = Vec2(q[0], q[1]);
        } else {
          has_uv = false;
        }
      }
      const Triangle tri{p[0], p[1], p[2]};
      if (is_degenerate(tri)) {
        ++degenerate;
        continue;
      }
      const Vec3 geo = glm::cross(p[1] - p[0], p[2] - p[0]);
      bool flip = false;
      TriangleShading sh;
      if (has_n) {
        const Vec3 avg = n[0] + n[1] + n[2];
        flip = glm::dot(avg, geo) < 0.f;
        // Flat-shaded faces (all normals equal) gain nothing from interpolation; keep the geometric normal.
        sh.has_normals = !(n[0] == n[1] && n[1] == n[2]);
        for (int k = 0; k < 3; ++k) sh.n[size_t(k)] = length_squared(n[k]) > 0.f ? glm::normalize(n[k]) : n[k];
      }
      if (has_uv)
        for (int k = 0; k < 3; ++k) sh.uv[size_t(k)] = uv[k];
      m.tris.push_back(tri);
      m.flip.push_back(flip);
      m.shading.push_back(sh);
      m.has_shading = m.has_shading || has_uv || sh.has_normals;
    }
  }
  if (degenerate > 0) ctx.warn(path, label + ": skipped " + std::to_string(degenerate) + " zero-area triangle(s)");
  if (m.tris.empty()) ctx.warn(path, label + ": no triangles with area");
  return m;
}

}  // namespace tessera
