// Resuming and refining renders (RenderOptions::previous, core/render/render_state.h): an interrupted render finished, and a
// finished one refined to more samples, come out bit for bit as an uninterrupted render, also through an EXR file.
// Interruptions are driven by the render's own progress callback or a tile budget, never by timing.
#include "core/render/render.h"

#include "core/render/render_state.h"
#include "core/scene/scene_loader.h"
#include "tests/support/test_files.h"

#include <gtest/gtest.h>
#include <tbb/global_control.h>
#include <tbb/task_arena.h>

#include <atomic>
#include <cstring>

namespace tessera {
namespace {

namespace fs = std::filesystem;

class RenderResume : public testing::TempDirTest {
 protected:
  // The course's textured Cornell box with a glass sphere, shrunk to 29 x 23 pixels.
  static Scene scene() {
    Scene s = load_scene_file(fs::path(TESSERA_COURSE_DIR) / "cbox_refract_textured.json").scene;
    s.width = 29;
    s.height = 23;
    return s;
  }
  static RenderOptions options(uint32_t spp, uint32_t replicates = 1) {
    RenderOptions ro;
    ro.seed = 99;
    ro.spp = spp;
    ro.variance = true;
    ro.tile_size = 4;
    ro.replicates = replicates;
    return ro;
  }
  // The state of a result as a later run sees it after an EXR round trip (write_state_channels, read_exr).
  StoredRender through_file(const RenderResult& r, uint32_t replicates) {
    Image img = r.image;
    write_state_channels(r.state, img);
    const fs::path p = file("state.exr");
    write_exr(p, img);
    const ExrImage back = read_exr(p);
    return StoredRender{back.pixels, read_state_channels(back.pixels, replicates)};
  }
};

// Bitwise equality of colours and of every float channel.
void expect_same_pixels(const Image& a, const Image& b) {
  ASSERT_EQ(a.rgb.size(), b.rgb.size());
  EXPECT_EQ(std::memcmp(a.rgb.data(), b.rgb.data(), a.rgb.size() * sizeof(float)), 0);
  ASSERT_EQ(a.extra.size(), b.extra.size());
  for (const auto& [name, ch] : a.extra) {
    ASSERT_TRUE(b.extra.count(name)) << name;
    EXPECT_EQ(std::memcmp(ch.data(), b.extra.at(name).data(), ch.size() * sizeof(float)), 0) << name;
  }
}

size_t unrendered(const RenderState& s) {
  size_t n = 0;
  for (const uint32_t v : s.samples) n += v == 0 ? 1 : 0;
  return n;
}

TEST(PixelAccumulatorState, RestoreContinuesBitForBit) {
  for (const uint32_t k : {1u, 3u}) {
    PixelAccumulator whole(k), first(k);
    for (int i = 0; i < 7; ++i) {
      const Vec3 v(0.1f * float(i) + 0.3f, 1.f / float(i + 3), float(i * i));
      whole.add(v);
      first.add(v);
    }
    std::vector<double> state(PixelAccumulator::state_size(k));
    ASSERT_EQ(PixelAccumulator::state_names(k).size(), state.size());
    first.save(state.data());
    PixelAccumulator cont = PixelAccumulator::restore(k, first.count(), state.data());
    for (int i = 7; i < 12; ++i) {
      const Vec3 v(std::sqrt(float(i)), 0.7f, 1e3f / float(i));
      whole.add(v);
      cont.add(v);
    }
    const PixelEstimate a = whole.estimate(), b = cont.estimate();
    EXPECT_EQ(std::memcmp(&a.mean, &b.mean, sizeof a.mean), 0) << k;
    EXPECT_EQ(std::memcmp(&a.var_mean, &b.var_mean, sizeof a.var_mean), 0) << k;
    EXPECT_EQ(a.spp, b.spp);
    EXPECT_EQ(whole.relative_error(0.01), cont.relative_error(0.01));
  }
}

TEST_F(RenderResume, CancelledFromProgressThenResumedIsBitwiseIdentical) {
  const Scene s = scene();
  const RenderOptions ro = options(8);
  const RenderResult whole = render(s, ro);
  ASSERT_FALSE(whole.cancelled);
  for (const bool exact : {false, true}) {
    // Cancelled from the render's own progress callback once 10 of its 48 tiles are done.
    std::atomic<bool> cancel{false};
    RenderOptions first = ro;
    first.keep_state = exact;
    first.cancel = &cancel;
    first.progress = [&](const RenderProgress& p) {
      if (p.tiles_done >= 10) cancel = true;
    };
    const RenderResult part = render(s, first);
    ASSERT_TRUE(part.cancelled);
    EXPECT_GT(unrendered(part.state), 0u);
    EXPECT_LT(unrendered(part.state), part.state.samples.size());
    EXPECT_EQ(part.state.exact(), exact);
    const StoredRender prev = through_file(part, 1);
    RenderOptions rest = ro;
    rest.previous = &prev;
    rest.tile_size = 7;  // tiles need not match
    const RenderResult done = render(s, rest);
    EXPECT_FALSE(done.cancelled);
    EXPECT_EQ(unrendered(done.state), 0u);
    expect_same_pixels(done.image, whole.image);
  }
}

TEST_F(RenderResume, TileBudgetRendersExactlyThatManyTiles) {
  const Scene s = scene();
  RenderOptions ro = options(2);
  ro.tile_budget = 5;
  ro.tile_size = 1;  // every tile one pixel, whichever tiles the threads take first
  const RenderResult part = render(s, ro);
  EXPECT_TRUE(part.cancelled);
  EXPECT_EQ(part.state.samples.size() - unrendered(part.state), 5u);
}

TEST_F(RenderResume, RefineToMoreSamplesIsBitwiseIdenticalToRenderingThemFromTheStart) {
  const Scene s = scene();
  // One stratified sequence, and 4 interleaved replicates: sample s is a function of s alone in both.
  for (const uint32_t k : {1u, 4u}) {
    RenderOptions n = options(4, k);
    n.keep_state = true;
    const RenderResult coarse = render(s, n);
    const RenderResult reference = render(s, options(16, k));
    const StoredRender prev = through_file(coarse, k);
    RenderOptions more = options(16, k);
    more.previous = &prev;
    more.keep_state = true;
    const RenderResult refined = render(s, more);
    expect_same_pixels(refined.image, reference.image);
    // A refinement interrupted after 3 tiles and finished from its own partial state also matches.
    std::atomic<bool> cancel{false};
    RenderOptions cut = more;
    cut.cancel = &cancel;
    cut.progress = [&](const RenderProgress& p) {
      if (p.tiles_done >= 3) cancel = true;
    };
    const RenderResult half_way = render(s, cut);
    ASSERT_TRUE(half_way.cancelled);
    const StoredRender prev2 = through_file(half_way, k);
    more.previous = &prev2;
    expect_same_pixels(render(s, more).image, reference.image);
  }
}

TEST_F(RenderResume, AdaptiveRenderResumesBitwise) {
  const Scene s = scene();
  RenderOptions ro = options(0);
  ro.target_error = 0.1f;
  ro.min_spp = 4;
  ro.max_spp = 64;
  const RenderResult whole = render(s, ro);
  RenderOptions first = ro;
  first.tile_budget = 7;
  const RenderResult part = render(s, first);
  ASSERT_TRUE(part.cancelled);
  const StoredRender prev = through_file(part, 1);
  RenderOptions rest = ro;
  rest.previous = &prev;
  expect_same_pixels(render(s, rest).image, whole.image);
}

TEST_F(RenderResume, RefusesWhatCannotContinueExactly) {
  const Scene s = scene();
  const RenderResult coarse = render(s, options(4));  // no exact sums kept
  StoredRender prev = through_file(coarse, 1);
  RenderOptions more = options(16);
  more.previous = &prev;
  EXPECT_THROW(render(s, more), std::invalid_argument);  // 4 of 16 samples and nothing to continue from
  RenderOptions fewer = options(2);
  fewer.previous = &prev;
  EXPECT_THROW(render(s, fewer), std::invalid_argument);  // more samples than asked for
  RenderOptions keep = options(4);
  keep.previous = &prev;
  keep.keep_state = true;
  EXPECT_THROW(render(s, keep), std::invalid_argument);  // cannot produce exact sums it never had
  RenderOptions other_k = options(4, 2);
  other_k.previous = &prev;
  EXPECT_THROW(render(s, other_k), std::invalid_argument);
  RenderOptions crop = options(4);
  crop.window = PixelWindow{0, 0, 5, 5};
  crop.previous = &prev;
  EXPECT_THROW(render(s, crop), std::invalid_argument);
  // The same spp with the same state: every pixel is copied.
  RenderOptions same = options(4);
  same.previous = &prev;
  expect_same_pixels(render(s, same).image, coarse.image);
}

TEST_F(RenderResume, StateChannelsRoundTripAndIncompleteOnesAreRefused) {
  const Scene s = scene();
  RenderOptions ro = options(3, 2);
  ro.keep_state = true;
  const RenderResult r = render(s, ro);
  const StoredRender back = through_file(r, 2);
  EXPECT_EQ(back.state.samples, r.state.samples);
  ASSERT_EQ(back.state.sums.size(), r.state.sums.size());
  EXPECT_EQ(std::memcmp(back.state.sums.data(), r.state.sums.data(), r.state.sums.size() * sizeof(double)), 0);
  Image missing = back.image;
  missing.uint_extra.erase(std::string(kStateChannelPrefix) + "rep1.Y.lo");
  EXPECT_THROW(read_state_channels(missing, 2), ImageError);
  EXPECT_THROW(read_state_channels(back.image, 3), ImageError);  // replicate count differs from the channels'
  Image none = back.image;
  none.uint_extra.clear();
  EXPECT_THROW(read_state_channels(none, 2), ImageError);
}

TEST_F(RenderResume, RowsOfStoppedTilesAreNeverToldFinal) {
  const Scene s = scene();  // 29 x 23: rows of 8 tiles of 4 x 4
  for (const int threads : {1, 3}) {
    RenderOptions ro = options(2);
    ro.tile_budget = 12;  // a row of tiles and a half
    int told = 0;
    ro.rows_final = [&](const Image&, const RenderState& state, int y0, int y1) {
      EXPECT_EQ(y0, told);
      told = y1;
      for (size_t i = size_t(y0) * 29; i < size_t(y1) * 29; ++i) EXPECT_EQ(state.samples[i], 2u) << i;
    };
    tbb::global_control allow(tbb::global_control::max_allowed_parallelism, size_t(threads));
    tbb::task_arena arena(threads);
    RenderResult part;
    arena.execute([&] { part = render(s, ro); });
    ASSERT_TRUE(part.cancelled);
    // One thread takes the tiles in order, so the budget ends inside the second row of tiles; more threads may
    // spend it on tiles of the first two rows in another order, and then tell at most the first.
    if (threads == 1) EXPECT_EQ(told, 4);
    else EXPECT_LE(told, 4);
  }
}

}  // namespace
}  // namespace tessera
