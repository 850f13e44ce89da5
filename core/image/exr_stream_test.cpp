// ExrStream: an EXR compressed band by band while a render goes on (RenderOptions::rows_final, as `tessera render`
// does it) is byte for byte the one write_exr writes of the finished image, for every compression, half and float
// colours, extra and state channels, sizes and windows that are no multiple of the tile or of the 16- and 32-row
// line blocks, and any thread count; whatever does not fit the stream is encoded afresh, with the same bytes.
#include "core/image/exr_stream.h"

#include "core/render/render.h"
#include "core/render/render_state.h"
#include "core/scene/scene_loader.h"
#include "tests/support/test_files.h"

#include <gtest/gtest.h>
#include <tbb/global_control.h>
#include <tbb/task_arena.h>

#include <algorithm>
#include <fstream>
#include <iterator>
#include <memory>
#include <string>

namespace tessera {
namespace {

namespace fs = std::filesystem;

// The course's textured Cornell box with a glass sphere at an odd size: 37 x 45 pixels.
const Scene& cbox() {
  static const Scene s = [] {
    Scene scene = load_scene_file(fs::path(TESSERA_COURSE_DIR) / "cbox_refract_textured.json").scene;
    scene.width = 37;
    scene.height = 45;
    return scene;
  }();
  return s;
}

// What a streamed render gave.
struct Streamed {
  RenderResult result;  // with the state channels in its image when kept, as the CLI writes them
  bool complete = false;  // the stream held every row when the render returned
  int bands = 0;          // calls of rows_final
  std::vector<uint8_t> bytes;  // finish() of a blank image of the file's layout (see below)
};

// Renders `ro` on `threads` threads, handing each band of final rows to an ExrStream laid out as `opt`, as
// `tessera render` does. finish() is then given a blank image of the same layout: if its bytes are the one-shot
// encoding of the rendered image, the stream's blocks were used as they are and are that encoding's.
Streamed render_streamed(const RenderOptions& ro, const ExrWriteOptions& opt, int threads) {
  ExrStream stream(opt);
  Streamed out;
  RenderOptions o = ro;
  o.rows_final = [&](const Image& film, const RenderState& state, int y0, int y1) {
    Image band = image_rows(film, y0, y1);
    if (o.keep_state) write_state_channels(state, band, size_t(y0) * size_t(film.width));
    stream.write_rows(band);
    ++out.bands;
  };
  tbb::global_control allow(tbb::global_control::max_allowed_parallelism, size_t(threads));
  tbb::task_arena arena(threads);
  arena.execute([&] { out.result = render(cbox(), o); });
  if (o.keep_state) write_state_channels(out.result.state, out.result.image);
  out.complete = stream.complete();
  Image blank = out.result.image;
  std::fill(blank.rgb.begin(), blank.rgb.end(), 0.f);
  for (auto& [name, values] : blank.extra) std::fill(values.begin(), values.end(), 0.f);
  for (auto& [name, values] : blank.uint_extra) std::fill(values.begin(), values.end(), 0U);
  out.bytes = stream.finish(blank, opt);
  return out;
}

std::vector<uint8_t> file_bytes(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

// A noisy image with a float and a UINT extra channel.
Image noisy(int w, int h) {
  Image img = Image::make(w, h);
  uint32_t x = 777;
  const auto next = [&] { return x = x * 1664525u + 1013904223u; };
  for (float& v : img.rgb) v = float(next() >> 8) * 0x1p-22f;
  img.extra["variance.G"].resize(size_t(w) * size_t(h));
  for (float& v : img.extra["variance.G"]) v = float(next() >> 8) * 0x1p-30f;
  img.uint_extra["tessera.samples"].resize(size_t(w) * size_t(h));
  for (uint32_t& v : img.uint_extra["tessera.samples"]) v = next() % 9;
  return img;
}

struct Layout {
  const char* name;
  PixelWindow window;  // the rendered window (empty: the whole image)
  int tile;            // tile edge: rows per band
};

TEST(ExrStream, StreamedRenderGivesWriteExrsBytes) {
  const Layout layouts[] = {
      {"whole, tile 5", {}, 5},                  // 9 bands of 5 rows against 16- and 32-row blocks
      {"crop, tile 7", {3, 7, 36, 44}, 7},       // 33 x 37 from row 7: bands of 7, last of 2
      {"whole, tile 40", {}, 40},                // bands of 40 and 5 rows: several blocks per band
  };
  const ExrCompression compressions[] = {ExrCompression::kZip, ExrCompression::kPiz, ExrCompression::kNone};
  for (const Layout& l : layouts)
    for (const ExrCompression c : compressions)
      for (const bool half : {false, true})
        for (const int threads : {1, 3}) {
          const std::string what = std::string(l.name) + ", compression " + std::to_string(int(c)) +
                                   (half ? ", half" : ", float") + ", " + std::to_string(threads) + " thread(s)";
          RenderOptions ro;
          ro.seed = 5;
          ro.spp = 2;
          ro.tile_size = l.tile;
          ro.window = l.window;
          ro.variance = half;  // extra float channels with half colours, and...
          ro.keep_state = !half || l.tile == 40;  // ...UINT state channels with float colours (and with both)
          ExrWriteOptions opt;
          opt.compression = c;
          opt.half = half;
          opt.data_window = l.window.empty() ? PixelWindow{0, 0, cbox().width, cbox().height} : l.window;
          opt.display_window = {0, 0, cbox().width, cbox().height};
          // Only finish() sees the metadata: the blocks were compressed under a header without it.
          opt.metadata = {{"tessera:renderSeconds", "0.123456"}, {"tessera:spp", "2"}};
          const Streamed s = render_streamed(ro, opt, threads);
          ASSERT_FALSE(s.result.cancelled) << what;
          EXPECT_TRUE(s.complete) << what;
          // One thread finishes the rows of tiles in order, each its own band; more may finish several at once.
          if (threads == 1) EXPECT_EQ(s.bands, (opt.data_window.height() + l.tile - 1) / l.tile) << what;
          else EXPECT_GE(s.bands, 1) << what;
          EXPECT_TRUE(s.bytes == encode_exr(s.result.image, opt)) << what;
        }
}

class ExrStreamFile : public testing::TempDirTest {};

TEST_F(ExrStreamFile, WriteGivesWriteExrsFile) {
  const Image img = noisy(23, 50);
  ExrWriteOptions opt;
  opt.data_window = {4, 3, 27, 53};
  opt.display_window = {0, 0, 30, 60};
  opt.metadata = {{"tessera:spp", "8"}};
  write_exr(file("one_shot.exr"), img, opt);
  const std::vector<uint8_t> one_shot = file_bytes(file("one_shot.exr"));
  // Every row streamed: the file is written from the blocks (given a blank image, it still holds img).
  ExrStream whole(opt);
  for (int y = 0; y < img.height; y += 9) whole.write_rows(image_rows(img, y, std::min(img.height, y + 9)));
  ASSERT_TRUE(whole.complete());
  EXPECT_EQ(whole.rows_written(), 50);
  Image blank = img;
  std::fill(blank.rgb.begin(), blank.rgb.end(), 0.f);
  whole.write(file("streamed.exr"), blank, opt);
  EXPECT_EQ(file_bytes(file("streamed.exr")), one_shot);
  // Rows missing: the image is encoded afresh.
  ExrStream part(opt);
  part.write_rows(image_rows(img, 0, 20));
  part.write(file("part.exr"), img, opt);
  EXPECT_EQ(file_bytes(file("part.exr")), one_shot);
  // A folder that does not exist: an error naming the file, nothing written.
  ExrStream lost(opt);
  lost.write_rows(img);
  const fs::path nowhere = file("no/such/dir/frame.exr");
  try {
    lost.write(nowhere, img, opt);
    ADD_FAILURE() << "no error";
  } catch (const ImageError& e) {
    EXPECT_NE(std::string(e.what()).find(nowhere.string()), std::string::npos) << e.what();
  }
  EXPECT_EQ(std::distance(fs::directory_iterator(file("")), fs::directory_iterator()), 3);  // no .tmp left
}

TEST(ExrStream, WhatDoesNotFitTheStreamIsEncodedAfresh) {
  const Image img = noisy(19, 37);
  ExrWriteOptions opt;
  opt.metadata = {{"tessera:spp", "3"}};
  opt.data_window = {0, 0, 19, 37};
  const auto streamed = [&](int rows, const Image& source) {
    auto s = std::make_unique<ExrStream>(opt);
    for (int y = 0; y < rows; y += 16) s->write_rows(image_rows(source, y, std::min(rows, y + 16)));
    return s;
  };
  {  // rows missing
    auto s = streamed(20, img);
    EXPECT_FALSE(s->complete());
    EXPECT_EQ(s->finish(img, opt), encode_exr(img, opt));
  }
  {  // every row, then spent by the first finish()
    auto s = streamed(37, img);
    EXPECT_TRUE(s->complete());
    EXPECT_EQ(s->finish(img, opt), encode_exr(img, opt));
    EXPECT_FALSE(s->complete());
    Image other = img;
    other.rgb[0] = 1e6f;
    EXPECT_EQ(s->finish(other, opt), encode_exr(other, opt));
  }
  {  // half colours at the end
    ExrWriteOptions half = opt;
    half.half = true;
    EXPECT_EQ(streamed(37, img)->finish(img, half), encode_exr(img, half));
  }
  {  // another data window, or none (the image's own)
    ExrWriteOptions moved = opt;
    moved.data_window = {1, 0, 20, 37};
    EXPECT_EQ(streamed(37, img)->finish(img, moved), encode_exr(img, moved));
    ExrWriteOptions own = opt;
    own.data_window = {};
    EXPECT_EQ(streamed(37, img)->finish(img, own), encode_exr(img, own));
  }
  {  // a channel added after the bands (a partial render's state), or extra channels left out
    Image without = img;
    without.uint_extra.clear();
    EXPECT_EQ(streamed(37, without)->finish(img, opt), encode_exr(img, opt));
    ExrWriteOptions colours_only = opt;
    colours_only.write_extra = false;
    EXPECT_EQ(streamed(37, img)->finish(img, colours_only), encode_exr(img, colours_only));
  }
  {  // an image encode_exr refuses is refused the same way
    Image bad = img;
    bad.extra["variance.G"].pop_back();
    EXPECT_THROW(streamed(37, img)->finish(bad, opt), ImageError);
  }
}

TEST(ExrStream, BadBandsAreRefusedAndStopTheStream) {
  const Image img = noisy(19, 37);
  ExrWriteOptions opt;
  opt.data_window = {0, 0, 19, 37};
  EXPECT_THROW(ExrStream(ExrWriteOptions{}), ImageError);  // no data window
  {
    ExrStream s(opt);
    EXPECT_THROW(s.write_rows(noisy(18, 4)), ImageError);  // another width
    EXPECT_THROW(s.write_rows(image_rows(img, 0, 4)), ImageError);  // stopped
    EXPECT_EQ(s.rows_written(), 0);
    EXPECT_EQ(s.finish(img, opt), encode_exr(img, opt));
  }
  {
    ExrStream s(opt);
    s.write_rows(image_rows(img, 0, 30));
    EXPECT_THROW(s.write_rows(image_rows(img, 0, 8)), ImageError);  // past the data window's 37 rows
    EXPECT_FALSE(s.complete());
    EXPECT_EQ(s.finish(img, opt), encode_exr(img, opt));
  }
  {
    ExrStream s(opt);
    s.write_rows(image_rows(img, 0, 10));
    Image band = image_rows(img, 10, 37);
    band.extra["variance.B"] = band.extra["variance.G"];
    EXPECT_THROW(s.write_rows(band), ImageError);  // channels other than the first band's
    EXPECT_EQ(s.rows_written(), 10);
    EXPECT_EQ(s.finish(img, opt), encode_exr(img, opt));
  }
}

TEST(ImageRows, CopiesEveryChannelOfTheRows) {
  const Image img = noisy(7, 9);
  const Image rows = image_rows(img, 2, 5);
  EXPECT_EQ(rows.width, 7);
  EXPECT_EQ(rows.height, 3);
  EXPECT_TRUE(std::equal(rows.rgb.begin(), rows.rgb.end(), img.rgb.begin() + 3 * 7 * 2));
  EXPECT_TRUE(std::equal(rows.extra.at("variance.G").begin(), rows.extra.at("variance.G").end(),
                         img.extra.at("variance.G").begin() + 7 * 2));
  EXPECT_TRUE(std::equal(rows.uint_extra.at("tessera.samples").begin(), rows.uint_extra.at("tessera.samples").end(),
                         img.uint_extra.at("tessera.samples").begin() + 7 * 2));
  EXPECT_EQ(image_rows(img, 9, 9).height, 0);
  EXPECT_THROW(image_rows(img, 3, 2), ImageError);
  EXPECT_THROW(image_rows(img, 0, 10), ImageError);
  Image bad = img;
  bad.extra["variance.G"].pop_back();
  EXPECT_THROW(image_rows(bad, 0, 1), ImageError);
}

}  // namespace
}  // namespace tessera
