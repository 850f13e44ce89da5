#include "core/image/exr_attribute_sizes.h"

#include <map>
#include <stdexcept>
#include <string>

namespace tessera {
namespace {

// Bytes OpenEXR 3 reads for a value of each fixed-size type (Xdr: little-endian, no padding).
const std::map<std::string, int64_t>& fixed_sizes() {
  static const std::map<std::string, int64_t> sizes = {
      {"box2i", 16}, {"box2f", 16}, {"chromaticities", 32}, {"compression", 1}, {"deepImageState", 1},
      {"double", 8}, {"envmap", 1}, {"float", 4}, {"int", 4}, {"keycode", 28}, {"lineOrder", 1},
      {"m33d", 72}, {"m33f", 36}, {"m44d", 128}, {"m44f", 64}, {"rational", 8}, {"tiledesc", 9},
      {"timecode", 8}, {"v2d", 16}, {"v2f", 8}, {"v2i", 8}, {"v3d", 24}, {"v3f", 12}, {"v3i", 12}};
  return sizes;
}

class Walk {
 public:
  Walk(Imf::IStream& is, uint64_t size) : is_(is), size_(size) {}

  // A NUL-terminated name of at most 255 characters.
  std::string name() {
    std::string s;
    for (;;) {
      const char c = byte();
      if (c == '\0') return s;
      if (s.size() >= 255) throw std::runtime_error("header name longer than 255 characters");
      s += c;
    }
  }
  int32_t int32() {
    unsigned char b[4];
    is_.read(reinterpret_cast<char*>(b), 4);
    return int32_t(uint32_t(b[0]) | uint32_t(b[1]) << 8 | uint32_t(b[2]) << 16 | uint32_t(b[3]) << 24);
  }
  char byte() {
    char c = 0;
    is_.read(&c, 1);
    return c;
  }
  uint64_t at() { return is_.tellg(); }
  void skip_to(uint64_t pos) { is_.seekg(pos); }
  uint64_t size() const { return size_; }

 private:
  Imf::IStream& is_;
  uint64_t size_;
};

[[noreturn]] void refuse(const std::string& attribute, const std::string& type, const std::string& why) {
  throw std::runtime_error("header attribute '" + attribute + "' (" + type + ") " + why);
}

// Checks one attribute's value, [start, end), as OpenEXR would read it; leaves the walk at `end`.
void check_value(Walk& w, const std::string& attribute, const std::string& type, uint64_t start, uint64_t end) {
  const uint64_t bytes = end - start;
  if (const auto it = fixed_sizes().find(type); it != fixed_sizes().end()) {
    if (bytes != uint64_t(it->second))
      refuse(attribute, type, "holds " + std::to_string(bytes) + " bytes, its type " + std::to_string(it->second));
  } else if (type == "chlist") {
    // Channels (name, then pixel type, linear flag and 3 reserved bytes, x and y sampling: 16 bytes) up to an empty name.
    for (;;) {
      if (w.at() >= end) refuse(attribute, type, "has no end of its channel list inside it");
      if (w.name().empty()) break;
      if (end - w.at() < 16) refuse(attribute, type, "ends inside a channel");
      w.skip_to(w.at() + 16);
    }
    if (w.at() != end) refuse(attribute, type, "ends its channel list before the attribute's end");
  } else if (type == "stringvector") {
    // Strings, each a 4-byte length and its characters, filling the attribute.
    while (w.at() < end) {
      if (end - w.at() < 4) refuse(attribute, type, "ends inside a string's length");
      const int32_t length = w.int32();
      if (length < 0 || uint64_t(length) > end - w.at()) refuse(attribute, type, "holds a string longer than itself");
      w.skip_to(w.at() + uint64_t(length));
    }
  } else if (type == "floatvector") {
    if (bytes % 4 != 0) refuse(attribute, type, "holds " + std::to_string(bytes) + " bytes, not whole floats");
  } else if (type == "preview") {
    if (bytes < 8) refuse(attribute, type, "is too short");
    const uint64_t width = uint32_t(w.int32()), height = uint32_t(w.int32());
    if (width != 0 && height > (bytes - 8) / 4 / width)
      refuse(attribute, type, "claims a " + std::to_string(width) + "x" + std::to_string(height) +
                                  " image larger than itself");
    if (8 + 4 * width * height != bytes) refuse(attribute, type, "does not hold exactly its image");
  } else if (type == "idmanifest") {
    if (bytes < 4) refuse(attribute, type, "is too short");
  }
  // string and unknown types: OpenEXR reads exactly the declared bytes.
  w.skip_to(end);
}

}  // namespace

void check_attribute_sizes(Imf::IStream& is, uint64_t size, bool multipart) {
  Walk w(is, size);
  for (bool first = true;; first = false) {
    std::string attribute = w.name();
    if (attribute.empty()) {
      if (first && multipart) throw std::runtime_error("multi-part file without a header");
      return;  // the end of a single header, or of a multi-part file's list of headers
    }
    for (; !attribute.empty(); attribute = w.name()) {
      const std::string type = w.name();
      const int32_t bytes = w.int32();
      const uint64_t start = w.at();
      if (bytes < 0 || start > w.size() || uint64_t(bytes) > w.size() - start)
        refuse(attribute, type, "claims " + std::to_string(bytes) + " bytes, more than the file has left");
      check_value(w, attribute, type, start, start + uint64_t(bytes));
    }
    if (!multipart) return;
  }
}

}  // namespace tessera
