// Output layers for compositing and denoising: which per-pixel quantities a render writes beside its colour, and the
// EXR channel names each one fills.
#pragma once

#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

namespace tessera {

/// One output layer. The first-hit layers (albedo to object_id, and the Cryptomatte ones) describe the first surface
/// a camera ray reaches that is not purely specular: a ray is followed through `refraction` and `glass` surfaces
/// (refracted, or reflected under total internal reflection) up to the scene's max_depth, as the denoising passes of
/// pbrt and Cycles do.
enum class Layer : uint8_t {
  kAlbedo,          ///< albedo.R/G/B: the surface's reflectance (diffuse texture; a conductor's normal-incidence Fresnel).
  kNormal,          ///< N.X/Y/Z: the world-space shading normal, turned towards the ray that hit it.
  kDepth,           ///< Z: distance from the eye along the viewing direction (camera-space depth).
  kPosition,        ///< P.X/Y/Z: the hit point in the scene file's coordinates.
  kMaterialId,      ///< material_id: 1 + the material's number (0: background or no material), most samples wins.
  kObjectId,        ///< object_id: 1 + the object's index in `objects` (0: background), most samples wins.
  kVariance,        ///< variance.R/G/B and samples: the variance of the pixel's mean, and its sample count.
  kCryptoMaterial,  ///< Cryptomatte of material names (core/image/cryptomatte.h).
  kCryptoObject,    ///< Cryptomatte of object names.
};

/// Names of the Layer values (command line, job API, EXR part names), in declaration order.
inline constexpr std::string_view kLayerNames[] = {"albedo",      "normal",   "depth",           "position",
                                                   "material_id", "object_id", "variance",       "crypto_material",
                                                   "crypto_object"};
inline constexpr int kLayerCount = int(sizeof(kLayerNames) / sizeof(kLayerNames[0]));

/// A set of layers, as bits (1 << Layer).
class LayerSet {
 public:
  constexpr LayerSet() = default;
  /// The set whose bits are `bits` (bits of no layer are dropped).
  static constexpr LayerSet from_bits(uint32_t bits) { return LayerSet(bits & ((1u << kLayerCount) - 1)); }
  constexpr uint32_t bits() const { return bits_; }
  constexpr bool empty() const { return bits_ == 0; }
  constexpr bool has(Layer l) const { return (bits_ >> unsigned(l)) & 1u; }
  void add(Layer l) { bits_ |= 1u << unsigned(l); }
  /// The layers in declaration order.
  std::vector<Layer> list() const;
  /// True when a layer other than variance needs the first-hit pass.
  constexpr bool needs_first_hit() const { return (bits_ & ~(1u << unsigned(Layer::kVariance))) != 0; }
  friend constexpr bool operator==(LayerSet a, LayerSet b) { return a.bits_ == b.bits_; }

 private:
  constexpr explicit LayerSet(uint32_t bits) : bits_(bits) {}
  uint32_t bits_ = 0;
};

/// Parses a comma-separated list of layer names ("albedo,normal"; "" is the empty set); throws
/// std::invalid_argument naming an unknown layer and the known ones.
LayerSet parse_layers(std::string_view list);

/// The comma-separated names of the set's layers, in declaration order ("" when empty).
std::string layers_to_string(LayerSet layers);

/// The EXR channels a layer fills, in the order they are written.
std::vector<std::string> layer_channels(Layer layer);

/// The channels of every layer of the set, layer by layer in declaration order.
std::vector<std::string> layer_channels(LayerSet layers);

/// Ranks (id, coverage pairs) a Cryptomatte layer stores per pixel: 6, in three RGBA channel groups.
inline constexpr int kCryptomatteRanks = 6;

}  // namespace tessera
