// The size of a Wavefront OBJ file counted before it is parsed: OBJ has no header, so the triangles and vertices its
// lines declare are counted with one pass over its text (tinyobjloader would allocate for every one of them first),
// and the file's byte count is bounded before it is read at all.
#pragma once

#include <cstdint>
#include <string_view>

namespace tessera {

/// Bytes an OBJ file may hold per triangle of AssetLimits::max_triangles (core/scene/load_options.h): room for a
/// triangle soup with a position, a normal and a texture coordinate per corner, written with long numbers.
inline constexpr uint64_t kObjBytesPerTriangle = 1024;
/// Vertex positions (and, separately, normals and texture coordinates) an OBJ file may hold per triangle of
/// AssetLimits::max_triangles: three, as a triangle soup has.
inline constexpr uint64_t kObjVerticesPerTriangle = 3;

/// What an OBJ file's lines declare, counted as tinyobjloader reads them: a line is ended by \n or \r, leading blanks
/// (spaces and tabs) are skipped, `v`, `vn` and `vt` lines hold one entry each, and an `f` line of k corners is k - 2
/// triangles once split.
struct ObjCounts {
  uint64_t triangles = 0;  ///< Triangles of every face of three or more corners.
  uint64_t positions = 0;  ///< `v` lines.
  uint64_t normals = 0;    ///< `vn` lines.
  uint64_t texcoords = 0;  ///< `vt` lines.
};

/// Counts `text`'s elements in one pass, allocating nothing.
ObjCounts count_obj(std::string_view text);

}  // namespace tessera
