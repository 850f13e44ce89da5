// The camera-centred frame of loaded scenes (core/render/camera_frame.h): positions far from the origin keep their
// differences to the camera exactly, the frame depends on the scene file alone, and small far features are reported.
#include "core/render/camera_frame.h"

#include "core/scene/scene_loader.h"
#include "tests/support/test_files.h"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

namespace tessera {
namespace {

using json = nlohmann::json;

TEST(CameraFrame, CentredOnTheCameraPositionAsWritten) {
  EXPECT_EQ(camera_frame(json{{"camera", {{"position", {1e7, -2.5, 3}}}}}).origin, glm::dvec3(1e7, -2.5, 3));
  // The loader's default camera position, also when the position is malformed (the camera parse reports that).
  for (const json& j : {json::object(), json{{"camera", {{"position", {1, 2}}}}}, json{{"camera", {{"position", "x"}}}},
                        json{{"camera", {{"position", {1, 2, 1e300}}}}}})
    EXPECT_EQ(camera_frame(j).origin, glm::dvec3(0, 0, 1)) << j.dump();
}

class CameraFrameLoad : public testing::TempDirTest {};

TEST_F(CameraFrameLoad, PositionsAreCameraRelativeInDouble) {
  json s = testing::minimal_scene();
  const double far = 1e7;  // float spacing 1 here: 0.25 would be lost if rounded before the subtraction
  s["camera"] = {{"position", {far, far, far + 4}}, {"look_at", {far, far, far}}, {"fov", 40}};
  s["integrator"]["point_light_position"] = {far + 0.5, far + 2, far};
  s["objects"] = json::array({{{"type", "sphere"}, {"center", {far + 0.25, far - 0.125, far}}, {"radius", 0.5},
                               {"material_name", "white_diffuse"}}});
  write("tri.obj", "v 0.25 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n");
  s["objects"].push_back({{"type", "mesh"}, {"path", "tri.obj"}, {"translate", {far, far, far}},
                          {"material_name", "white_diffuse"}});
  const LoadedScene l = load_scene_file(write_scene("far.json", s));
  EXPECT_TRUE(l.warnings.empty()) << l.warnings[0];
  const Scene& sc = l.scene;
  EXPECT_EQ(sc.frame_origin, glm::dvec3(far, far, far + 4));
  EXPECT_EQ(sc.camera.position, Vec3(0.f));
  EXPECT_EQ(sc.spheres.at(0).center, Vec3(0.25f, -0.125f, -4.f));
  EXPECT_EQ(sc.point_light->position, Vec3(0.5f, 2.f, -4.f));
  EXPECT_EQ(sc.triangles.at(0).p0, Vec3(0.25f, 0.f, -4.f));
}

TEST_F(CameraFrameLoad, SmallFeaturesFarFromTheCameraAreReported) {
  json s = testing::minimal_scene();
  s["camera"] = {{"position", {0, 0, 0}}, {"look_at", {0, 0, -1}}, {"fov", 40}};
  s["objects"] = json::array({{{"type", "sphere"}, {"center", {0, 0, -1e6}}, {"radius", 1}, {"material_name", "white_diffuse"}}});
  LoadedScene l = load_scene_file(write_scene("a.json", s));  // spacing 1/16 at 1e6: radius 16 spacings
  ASSERT_EQ(l.warnings.size(), 1u);
  EXPECT_NE(l.warnings[0].find("1 primitive(s)"), std::string::npos) << l.warnings[0];
  s["objects"][0]["radius"] = 4;  // 64 spacings
  EXPECT_TRUE(load_scene_file(write_scene("b.json", s)).warnings.empty());
}

}  // namespace
}  // namespace tessera
