// Uncompressed scanline OpenEXR files written directly, for callers that build an OpenEXR header and frame buffer
// themselves (core's EXR encoder, the coordinator's merged result). Needs OpenEXR's headers and library.
#pragma once

#include <OpenEXR/ImfFrameBuffer.h>
#include <OpenEXR/ImfHeader.h>
#include <OpenEXR/ImfIO.h>

namespace tessera {

/// Writes an uncompressed single-part scanline file of `header` (NO_COMPRESSION, increasing y) with the pixels of
/// `frame` to os, bitwise the file OpenEXR's OutputFile writes, without handing each line to OpenEXR's thread pool: for
/// an uncompressed file OutputFile makes every line a task of that pool and waits for it, two context switches per line
/// once the pool has threads (it has them once any image was decoded or compressed on them). Returns false, having
/// written nothing, for a layout it does not write (another compression or line order, a tiled header, a subsampled
/// channel, a channel without a slice of its own type, a preview image); the caller then uses OutputFile. Throws, as
/// OutputFile does, for a header that fails Imf::Header::sanityCheck, and for the stream's errors.
bool write_uncompressed_exr(Imf::OStream& os, const Imf::Header& header, const Imf::FrameBuffer& frame);

}  // namespace tessera
