// Multi-part OpenEXR files: an image's channels split into named parts (one per output layer), written and read
// back as one image.
#pragma once

#include "core/image/image.h"

#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

namespace tessera {

/// One part after the first: its name and the image's extra channels it holds.
struct ExrPart {
  std::string name;                   ///< The part's name attribute (e.g. "albedo").
  std::vector<std::string> channels;  ///< Extra channels of the image, each in one part only.
};

/// The bytes of a multi-part EXR of img: part "rgba" holds R,G,B and every channel no entry of `parts` names, then
/// one part per entry of `parts` with its channels (float). Every part has opt's windows, compression and metadata;
/// opt.half applies to the colours. Throws ImageError for a channel the image lacks or one named twice.
std::vector<uint8_t> encode_exr_multipart(const Image& img, const ExrWriteOptions& opt, const std::vector<ExrPart>& parts);

/// Writes encode_exr_multipart's bytes to path atomically, as write_exr does. Throws ImageError naming the file.
void write_exr_multipart(const std::filesystem::path& path, const Image& img, const ExrWriteOptions& opt,
                         const std::vector<ExrPart>& parts);

/// read_exr, then the channels of every further part of a multi-part file (each part's data window must be the
/// first's) into pixels.extra; the metadata is the first part's. Throws as read_exr does, and ImageError for parts
/// of other windows or channel names met twice.
ExrImage read_exr_all_parts(const std::filesystem::path& path, const ExrReadOptions& options = {});

}  // namespace tessera
