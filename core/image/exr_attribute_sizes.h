// A hostile OpenEXR header bounded before OpenEXR's C++ library reads it. The library allocates what a string, a
// string vector, an unknown attribute or a preview image claims before it reads the value, and reads a typed value
// (a channel list, a box, ...) by its type, whatever size the attribute declares; so a short file could make it
// allocate gigabytes, directly or after its reading had drifted from the attributes' declared bounds. Needs
// OpenEXR's headers.
#pragma once

#include <OpenEXR/ImfIO.h>

#include <cstdint>

namespace tessera {

/// Walks every attribute of the file's header (of every header of a multi-part file) from is, positioned just after
/// the version field, and leaves is anywhere. Throws std::runtime_error naming the attribute when one declares more
/// bytes than the file of `size` bytes has after it, or a size its type cannot have (a value of a fixed-size type, a
/// channel list, a string vector or a float vector that does not fill its attribute exactly as OpenEXR reads it; a
/// preview image larger than its attribute), or when a name is over 255 characters. What passes is read by OpenEXR
/// along the same bounds, allocating at most about the file's size.
void check_attribute_sizes(Imf::IStream& is, uint64_t size, bool multipart);

}  // namespace tessera
