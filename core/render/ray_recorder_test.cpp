// RenderOptions::recorder sees exactly the rays a render counts, each with its kind, and changes no pixel.
#include "core/render/ray_recorder.h"
#include "core/render/render.h"
#include "core/scene/scene_loader.h"

#include <gtest/gtest.h>

#include <array>
#include <cstring>
#include <filesystem>
#include <mutex>
#include <string>
#include <vector>

namespace tessera {
namespace {

const std::filesystem::path kRecorderScenes = std::filesystem::path(TESSERA_SOURCE_DIR) / "scenes";

// Counts the rays it sees by kind (from any thread) and keeps the shadow rays' extents.
class CountingRecorder final : public RayRecorder {
 public:
  void record(RayKind kind, const Ray& r) override {
    std::lock_guard lock(mu_);
    ++by_kind[size_t(kind)];
    if (traced_as_any_hit(kind)) shadow_tmax.push_back(r.tmax);
  }
  std::array<uint64_t, kRayKinds> by_kind{};
  std::vector<float> shadow_tmax;

 private:
  std::mutex mu_;
};

struct RecorderCase {
  std::string scene;
  bool specular, bounce;  // whether the scene must produce rays of these kinds
};

TEST(RayRecorder, SeesEveryCountedRayWithItsKindAndChangesNoPixel) {
  // The direct integrator through a glass sphere (camera, specular, shadow rays); the path tracer with glass and
  // metal (camera, specular, bounce, shadow rays).
  for (const RecorderCase& c : {RecorderCase{"cbox_no_light_refraction", true, false}, RecorderCase{"cbox_glass", true, true}}) {
    SCOPED_TRACE(c.scene);
    const Scene scene = load_scene_file(kRecorderScenes / (c.scene + ".json")).scene;
    RenderOptions o;
    o.spp = 4;
    o.seed = 3;
    o.window = PixelWindow{scene.width / 2 - 24, scene.height / 2 - 24, scene.width / 2 + 24, scene.height / 2 + 24};
    o.tile_size = 8;
    const RenderResult plain = render(scene, o);
    CountingRecorder rec;
    o.recorder = &rec;
    const RenderResult recorded = render(scene, o);

    ASSERT_EQ(plain.image.rgb.size(), recorded.image.rgb.size());
    EXPECT_EQ(0, std::memcmp(plain.image.rgb.data(), recorded.image.rgb.data(), plain.image.rgb.size() * sizeof(float)));
    EXPECT_EQ(plain.counters.rays, recorded.counters.rays);

    uint64_t total = 0;
    for (const uint64_t n : rec.by_kind) total += n;
    EXPECT_EQ(total, recorded.counters.rays);
    EXPECT_EQ(rec.by_kind[size_t(RayKind::kCamera)], recorded.counters.camera);
    EXPECT_EQ(recorded.counters.camera, uint64_t(48 * 48 * 4));
    EXPECT_EQ(rec.by_kind[size_t(RayKind::kSpecular)] > 0, c.specular);
    EXPECT_EQ(rec.by_kind[size_t(RayKind::kBounce)] > 0, c.bounce);
    EXPECT_GT(rec.by_kind[size_t(RayKind::kShadow)], 0u);
    // Shadow rays towards area lights and the point light end short of their target; environment ones do not end.
    for (const float t : rec.shadow_tmax) EXPECT_GT(t, 0.f);
  }
}

}  // namespace
}  // namespace tessera
