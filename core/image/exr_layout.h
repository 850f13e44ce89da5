// How an Image is laid out as an OpenEXR file: the pieces write_exr and ExrStream share. Internal to core/ (it
// includes OpenEXR's headers, which core/ links privately); the public interface is core/image/image.h and core/image/exr_stream.h.
#pragma once

#include "core/image/exr_io.h"
#include "core/image/image.h"

#include <OpenEXR/ImfFrameBuffer.h>
#include <OpenEXR/ImfHeader.h>
#include <OpenEXR/ImfIO.h>
#include <Imath/half.h>

#include <cstdint>
#include <filesystem>
#include <string>
#include <string_view>
#include <vector>

namespace tessera::exr_layout {

/// The data window of a file of img written with opt (opt.data_window, or img's size at the origin). Throws
/// std::runtime_error for a malformed or empty img, or a data window of another width (and, unless `band`, height).
PixelWindow data_window(const Image& img, const ExrWriteOptions& opt, bool band = false);

/// The header write_exr writes for an image with img's channels laid out as opt says over `data`: windows,
/// compression, opt.metadata, and the channels R,G,B (float or half) plus, with opt.write_extra, img's extra
/// channels (float) and uint_extra channels (UINT). Throws std::runtime_error for metadata that names a standard
/// attribute and for colliding channel names.
Imf::Header header(const Image& img, const ExrWriteOptions& opt, const PixelWindow& data);

/// A frame buffer over img's channels, img holding the pixels of `rows` (a window of whole rows of the data window,
/// in EXR pixel space), with the half copy of its colours that half output needs.
struct Frame {
  Imf::FrameBuffer buffer;     ///< The slices, addressed by absolute pixel coordinates.
  std::vector<half> rgb_half;  ///< img's colours as half (opt.half only); the colour slices point into it.
};

/// Throws std::runtime_error when an extra channel that opt writes has another size than img's.
void check_extra_sizes(const Image& img, const ExrWriteOptions& opt);

/// The frame of img's channels as header(img, opt, ...) lists them; throws as check_extra_sizes does.
Frame frame(const Image& img, const ExrWriteOptions& opt, const PixelWindow& rows);

/// encode_exr's bytes, throwing std::runtime_error (or OpenEXR's errors) without context; `name` appears in
/// OpenEXR's messages.
std::vector<uint8_t> encode(const char* name, const Image& img, const ExrWriteOptions& opt);

/// Threads for compressing an EXR: as many as the render may use (--threads), OpenEXR's pool resized to that.
int compression_threads();

}  // namespace tessera::exr_layout
