#include "server/tile_state.h"

#include "core/render/render.h"
#include "core/render/render_state.h"
#include "core/scene/scene_loader.h"
#include "server/database.h"
#include "core/util/file_io.h"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <filesystem>

namespace tessera::server {
namespace {

namespace fs = std::filesystem;

// A small analytic scene (no assets), 11x9 pixels.
LoadedScene small_scene() {
  const nlohmann::json j = nlohmann::json::parse(R"({
    "integrator": {"type": "intersection_test", "spp": 4, "point_light_position": [0, 3, 3],
                   "point_light_flux": [40, 40, 40]},
    "film": {"resolution": [11, 9]},
    "camera": {"position": [0, 0.3, 4], "look_at": [0, 0, 0], "fov": 45},
    "textures": {"white": {"type": "constant", "color": [0.8, 0.7, 0.6]}},
    "materials": {"m": {"type": "diffuse", "texture_name": "white"}},
    "objects": [{"type": "sphere", "center": [0, 0, 0], "radius": 0.9, "material_name": "m"}]})");
  return load_scene_json(j, "scene", [](const std::string& p, const std::string&) { return fs::path(p); });
}

// The window rendered at spp with its exact sums, as a worker uploads a resumable tile (pixels + state channels).
Image rendered_tile(const Scene& scene, const PixelWindow& window, uint32_t spp, uint32_t replicates = 1) {
  RenderOptions ro;
  ro.spp = spp;
  ro.seed = 3;
  ro.window = window;
  ro.replicates = replicates;
  ro.keep_state = true;
  RenderResult r = render(scene, ro);
  write_state_channels(r.state, r.image);
  return r.image;
}

TEST(TileState, AnUploadIsAStateWhenEveryPixelHasTheSppAndItsColourIsTheMeanOfItsSums) {
  const LoadedScene s = small_scene();
  const PixelWindow w{2, 1, 7, 5};
  EXPECT_EQ(check_tile_state(rendered_tile(s.scene, w, 4), 4, 1), std::nullopt);
  EXPECT_EQ(check_tile_state(rendered_tile(s.scene, w, 4, 2), 4, 2), std::nullopt);

  const auto error = [](const std::optional<std::string>& e) { return e.value_or("(accepted)"); };
  EXPECT_EQ(error(check_tile_state(rendered_tile(s.scene, w, 8), 4, 1)),
            "8 samples at tile pixel (0, 0), the job has 4 spp");
  Image tampered = rendered_tile(s.scene, w, 4);
  tampered.rgb[3 * 6 + 1] += 0.125f;  // pixel (1, 1), green
  EXPECT_EQ(error(check_tile_state(tampered, 4, 1)), "the colour at tile pixel (1, 1) is not the mean of its stored sums");
  Image no_sums = rendered_tile(s.scene, w, 4);
  for (auto it = no_sums.uint_extra.begin(); it != no_sums.uint_extra.end();)
    it = it->first.starts_with(kStateChannelPrefix) ? no_sums.uint_extra.erase(it) : std::next(it);
  EXPECT_NE(error(check_tile_state(no_sums, 4, 1)).find("needs its exact sums: no tessera.state."), std::string::npos);
  Image plain = rendered_tile(s.scene, w, 4);
  plain.uint_extra.clear();
  EXPECT_NE(error(check_tile_state(plain, 4, 1)).find("no tessera.samples channel"), std::string::npos);
  // Replicates change the channel list: a one-replicate state is not a two-replicate one.
  EXPECT_NE(error(check_tile_state(rendered_tile(s.scene, w, 4), 4, 2)).find("accumulator channels"), std::string::npos);
}

TEST(TileState, TheResultsStateChannelsAreTheWholeImagesGatheredFromTheStoredTiles) {
  const LoadedScene s = small_scene();
  const fs::path dir = fs::temp_directory_path() / ("tessera-tile-state-test-" + random_hex(6));
  {
    DurableStore store(dir);
    const TileGrid grid(11, 9, 4);  // 3x3 tiles, ragged edges
    for (int64_t t = 0; t < grid.count(); ++t) {
      ExrWriteOptions o;
      o.data_window = grid.window(t);
      o.display_window = PixelWindow{0, 0, 11, 9};
      const std::vector<uint8_t> exr = encode_exr(rendered_tile(s.scene, grid.window(t), 6), o);
      store.save_tile_state("j-1", t, 6, std::string(exr.begin(), exr.end()));
    }
    const Image whole = rendered_tile(s.scene, PixelWindow{0, 0, 11, 9}, 6);
    EXPECT_EQ(result_state_channels(store, "j-1", grid, 6, 1), whole.uint_extra);
    try {
      result_state_channels(store, "j-1", grid, 12, 1);
      ADD_FAILURE() << "a state of another spp was gathered";
    } catch (const std::runtime_error& e) {
      EXPECT_STREQ(e.what(), "tile 0's stored state has 6 spp, not 12");
    }
    try {
      result_state_channels(store, "j-2", grid, 6, 1);
      ADD_FAILURE() << "a job without states was gathered";
    } catch (const std::runtime_error& e) {
      EXPECT_STREQ(e.what(), "tile 0 has no stored state");
    }
  }
  fs::remove_all(dir);
}

}  // namespace
}  // namespace tessera::server
