#include "server/preview.h"

#include <OpenEXR/ImfChannelList.h>
#include <OpenEXR/ImfFrameBuffer.h>
#include <OpenEXR/ImfHeader.h>
#include <OpenEXR/ImfInputFile.h>

#include <algorithm>
#include <stdexcept>
#include <string>

namespace tessera::server {

PreviewDownsampler::PreviewDownsampler(int width, int height) : width_(width), height_(height) {
  if (width <= 0 || height <= 0) throw std::invalid_argument("a preview needs a frame of positive size");
  factor_ = (std::max(width, height) + kMaxPreviewSide - 1) / kMaxPreviewSide;
  preview_ = Image::make((width + factor_ - 1) / factor_, (height + factor_ - 1) / factor_);
  sums_.assign(3 * size_t(preview_.width), 0.f);
}

void PreviewDownsampler::add_row(const float* rgb) {
  if (next_row_ >= height_) throw std::logic_error("PreviewDownsampler: more rows than the frame has");
  // Each block's sum gathers its rows top to bottom and each row's pixels left to right.
  for (int sx = 0; sx < preview_.width; ++sx) {
    float* sum = &sums_[3 * size_t(sx)];
    const int x1 = std::min(width_, (sx + 1) * factor_);
    for (int x = sx * factor_; x < x1; ++x)
      for (int c = 0; c < 3; ++c) sum[c] += rgb[3 * size_t(x) + size_t(c)];
  }
  ++next_row_;
  if (next_row_ % factor_ == 0 || next_row_ == height_) flush_block_row();
}

void PreviewDownsampler::flush_block_row() {
  const int sy = (next_row_ - 1) / factor_;
  const int rows = next_row_ - sy * factor_;
  for (int sx = 0; sx < preview_.width; ++sx) {
    const int columns = std::min(width_, (sx + 1) * factor_) - sx * factor_;
    const float* sum = &sums_[3 * size_t(sx)];
    preview_.set(sx, sy, Vec3(sum[0], sum[1], sum[2]) * (1.f / float(rows * columns)));
  }
  std::fill(sums_.begin(), sums_.end(), 0.f);
}

Image PreviewDownsampler::take() { return std::move(preview_); }

Image preview_image(const Image* image, int width, int height) {
  PreviewDownsampler down(width, height);
  if (image)
    for (int y = 0; y < height; ++y) down.add_row(&image->rgb[3 * size_t(y) * size_t(width)]);
  return down.take();
}

std::vector<uint8_t> preview_png(const Image* image, int width, int height) {
  if (image && std::max(width, height) <= kMaxPreviewSide) return encode_png_srgb(*image);
  return encode_png_srgb(preview_image(image, width, height));
}

Image preview_image_of_exr(const std::filesystem::path& file, int width, int height) {
  try {
    Imf::InputFile in(file.c_str(), 0);
    const Imath::Box2i dw = in.header().dataWindow();
    if (dw.min.x != 0 || dw.min.y != 0 || dw.max.x != width - 1 || dw.max.y != height - 1)
      throw std::runtime_error("its data window is not the job's " + std::to_string(width) + "x" +
                               std::to_string(height) + " frame");
    for (const char* c : {"R", "G", "B"})
      if (!in.header().channels().findChannel(c)) throw std::runtime_error(std::string("it has no ") + c + " channel");
    PreviewDownsampler down(width, height);
    const size_t row_floats = 3 * size_t(width);
    std::vector<float> rows(row_floats * kPreviewReadRows);
    for (int y0 = 0; y0 < height; y0 += kPreviewReadRows) {
      const int y1 = std::min(height, y0 + kPreviewReadRows);
      // The buffer holds rows [y0, y1): the frame buffer addresses pixels by absolute row, so its origin lies y0 rows
      // before the buffer.
      const intptr_t origin = intptr_t(rows.data()) - intptr_t(y0) * intptr_t(row_floats * sizeof(float));
      Imf::FrameBuffer fb;
      const char* const names[] = {"R", "G", "B"};
      for (size_t c = 0; c < 3; ++c)
        fb.insert(names[c], Imf::Slice(Imf::FLOAT, reinterpret_cast<char*>(origin + intptr_t(c * sizeof(float))),
                                       3 * sizeof(float), row_floats * sizeof(float)));
      in.setFrameBuffer(fb);
      in.readPixels(y0, y1 - 1);
      for (int y = y0; y < y1; ++y) down.add_row(&rows[size_t(y - y0) * row_floats]);
    }
    return down.take();
  } catch (const std::exception& e) {
    throw ImageError("cannot read EXR \"" + file.string() + "\" for a preview: " + e.what());
  }
}

std::vector<uint8_t> preview_png_of_exr(const std::filesystem::path& file, int width, int height) {
  return encode_png_srgb(preview_image_of_exr(file, width, height));
}

}  // namespace tessera::server
