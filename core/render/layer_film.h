// The first-hit output layers of a render (core/render/layers.h): their channels in the render's image and the pass
// that fills one pixel of them from its camera samples.
#pragma once

#include "core/image/exr_multipart.h"
#include "core/image/image.h"
#include "core/render/layers.h"
#include "core/render/scene.h"

#include <cstdint>
#include <map>
#include <string>
#include <utility>
#include <vector>

namespace tessera {

/// Per-thread working space of LayerFilm::render_pixel (so that a pixel allocates nothing once warm).
struct LayerScratch {
  std::vector<std::pair<uint32_t, uint32_t>> materials;  ///< (material, samples) of the pixel.
  std::vector<std::pair<uint32_t, uint32_t>> objects;    ///< (object, samples) of the pixel.
  std::vector<std::pair<uint32_t, uint32_t>> crypto;     ///< (Cryptomatte id, samples), merged by id.
};

/// The first-hit layers' channels of an image (every layer of the set but variance, which render() fills).
///
/// A pixel's value is a pure function of the scene, the seed, the pixel and its sample count n: each of its samples
/// 0..n-1 sends the camera ray its beauty sample sends (the same sampler, first 2D draw) to first_hit(); the
/// samples are summed in order in double precision. albedo and N are means over all n samples (a sample that
/// reaches nothing adds zero); P and Z are means over the samples that reached a surface (P 0 and Z +infinity when
/// none did); material_id and object_id are the id most samples reached, the background (0) included, ties going
/// to the smaller id; a Cryptomatte layer holds up to kCryptomatteRanks (id, coverage) pairs by falling coverage
/// (ties by id), coverage being samples / n, the background left out.
class LayerFilm {
 public:
  /// Adds the channels of `layers` but variance to img (zeroed), remembering where they are; nothing when the set
  /// needs no first-hit pass. The scene must outlive the film.
  LayerFilm(const Scene& scene, LayerSet layers, Image& img);

  /// True when the set has a first-hit layer.
  bool active() const { return active_; }

  /// Fills pixel i of the channels from samples [0, n) of image pixel (px, row), sampled as render() samples them
  /// (seed and replicates as RenderOptions). n = 0 leaves the pixel as it is.
  void render_pixel(int px, int row, uint64_t seed, uint32_t n, uint32_t replicates, size_t i,
                    LayerScratch& scratch) const;

 private:
  const Scene& scene_;
  LayerSet layers_;
  bool active_ = false;
  bool need_materials_ = false, need_objects_ = false;
  float* albedo_[3] = {};
  float* normal_[3] = {};
  float* depth_ = nullptr;
  float* position_[3] = {};
  float* material_id_ = nullptr;
  float* object_id_ = nullptr;
  float* crypto_material_[2 * kCryptomatteRanks] = {};
  float* crypto_object_[2 * kCryptomatteRanks] = {};
  std::vector<uint32_t> material_crypto_;  // per material: its Cryptomatte id (0 for none)
  std::vector<uint32_t> object_crypto_;    // per object + 1: its Cryptomatte id (0 for none)
};

/// The EXR header attributes of the set's Cryptomatte layers for the scene (cryptomatte_metadata of its material
/// and object names); empty without one.
std::map<std::string, std::string> layer_metadata(const Scene& scene, LayerSet layers);

/// The parts of a multi-part EXR of img (write_exr_multipart): one per layer whose channels img has, named as the
/// layer; the colour and any other channel stay in the first part.
std::vector<ExrPart> layer_parts(const Image& img);

}  // namespace tessera
