#include "core/scene/scene_validate.h"

#include "core/render/camera_frame.h"
#include "core/geometry/coincident.h"

#include <map>
#include <utility>

namespace tessera {

void validate_scene(const Scene& s, SceneJson& ctx) {
  // Exactly coincident triangles (z-fighting), one warning per pair of objects.
  std::map<std::pair<uint32_t, uint32_t>, size_t> per_objects;
  for (const CoincidentPair& c : find_coincident_triangles(s.triangles))
    ++per_objects[{s.triangle_object[c.first], s.triangle_object[c.second]}];
  for (const auto& [objs, count] : per_objects) {
    const std::string a = "objects[" + std::to_string(objs.first) + "]", b = "objects[" + std::to_string(objs.second) + "]";
    ctx.warn(b, std::to_string(count) + " triangle(s) coincide exactly with triangles of " +
                    (objs.first == objs.second ? std::string("the same object") : a) +
                    "; which one is visible there is arbitrary (is a mesh listed twice?)");
  }
  // Far from the camera (the far-from-origin check of a camera-relative frame): never an error, even with --strict.
  for (std::string& w : precision_warnings(s, ctx.name)) ctx.out.warnings.push_back(std::move(w));
}

}  // namespace tessera
