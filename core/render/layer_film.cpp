#include "core/render/layer_film.h"

#include "core/image/cryptomatte.h"
#include "core/render/first_hit.h"
#include "core/render/render.h"
#include "core/util/zeroed_buffer.h"

#include <algorithm>
#include <limits>

namespace tessera {

namespace {

// Adds one sample of `id` to the pixel's (id, samples) list.
void tally(std::vector<std::pair<uint32_t, uint32_t>>& ids, uint32_t id) {
  for (auto& e : ids)
    if (e.first == id) {
      ++e.second;
      return;
    }
  ids.emplace_back(id, 1u);
}

// The id with the most samples (ties: the smaller id).
uint32_t most_covering(const std::vector<std::pair<uint32_t, uint32_t>>& ids) {
  uint32_t best = 0, best_n = 0;
  for (const auto& [id, n] : ids)
    if (n > best_n || (n == best_n && id < best)) best = id, best_n = n;
  return best;
}

// Writes the Cryptomatte ranks of the pixel's ids (mapped through `crypto`, 0 = left out) to ch[0..2 ranks).
void write_crypto(float* const* ch, size_t i, const std::vector<std::pair<uint32_t, uint32_t>>& ids,
                  const std::vector<uint32_t>& crypto, uint32_t n, std::vector<std::pair<uint32_t, uint32_t>>& merged) {
  merged.clear();
  for (const auto& [id, c] : ids) {
    const uint32_t h = id < crypto.size() ? crypto[id] : 0u;
    if (h == 0) continue;
    auto it = std::find_if(merged.begin(), merged.end(), [h](const auto& e) { return e.first == h; });
    if (it == merged.end()) merged.emplace_back(h, c);
    else it->second += c;
  }
  std::sort(merged.begin(), merged.end(),
            [](const auto& a, const auto& b) { return a.second != b.second ? a.second > b.second : a.first < b.first; });
  for (int r = 0; r < kCryptomatteRanks; ++r) {
    const bool present = size_t(r) < merged.size();
    ch[2 * r][i] = present ? cryptomatte_float(merged[size_t(r)].first) : 0.f;
    ch[2 * r + 1][i] = present ? float(double(merged[size_t(r)].second) / double(n)) : 0.f;
  }
}

}  // namespace

LayerFilm::LayerFilm(const Scene& scene, LayerSet layers, Image& img) : scene_(scene), layers_(layers) {
  active_ = layers.needs_first_hit();
  if (!active_) return;
  const size_t npix = size_t(img.width) * size_t(img.height);
  const auto channels = [&](Layer l, float** out) {
    if (!layers.has(l)) return;
    const std::vector<std::string> names = layer_channels(l);
    for (size_t c = 0; c < names.size(); ++c) {
      std::vector<float>& ch = img.extra[names[c]];
      assign_zeroed(ch, npix);
      out[c] = ch.data();
    }
  };
  channels(Layer::kAlbedo, albedo_);
  channels(Layer::kNormal, normal_);
  channels(Layer::kDepth, &depth_);
  channels(Layer::kPosition, position_);
  channels(Layer::kMaterialId, &material_id_);
  channels(Layer::kObjectId, &object_id_);
  channels(Layer::kCryptoMaterial, crypto_material_);
  channels(Layer::kCryptoObject, crypto_object_);
  need_materials_ = layers.has(Layer::kMaterialId) || layers.has(Layer::kCryptoMaterial);
  need_objects_ = layers.has(Layer::kObjectId) || layers.has(Layer::kCryptoObject);
  if (layers.has(Layer::kCryptoMaterial)) {
    material_crypto_.assign(scene.materials.size(), 0u);
    for (size_t m = 1; m < scene.material_names.size() && m < material_crypto_.size(); ++m)
      material_crypto_[m] = cryptomatte_id(scene.material_names[m]);
  }
  if (layers.has(Layer::kCryptoObject)) {
    object_crypto_.assign(scene.object_names.size() + 1, 0u);
    for (size_t o = 0; o < scene.object_names.size(); ++o) object_crypto_[o + 1] = cryptomatte_id(scene.object_names[o]);
  }
}

void LayerFilm::render_pixel(int px, int row, uint64_t seed, uint32_t n, uint32_t replicates, size_t i,
                             LayerScratch& scratch) const {
  if (!active_ || n == 0) return;
  const Scene& scene = scene_;
  const uint32_t key = PixelSampler::pixel_key(seed, px, row);
  glm::dvec3 albedo(0.0), normal(0.0), position(0.0);
  double depth = 0.0;
  uint32_t hits = 0;
  scratch.materials.clear();
  scratch.objects.clear();
  const glm::dvec3 eye(scene.camera.position), forward(scene.camera.forward);
  for (uint32_t s = 0; s < n; ++s) {
    PixelSampler sampler = replicates <= 1 ? PixelSampler(key, s) : pixel_sampler(seed, px, row, s, replicates);
    const FirstHit f =
        first_hit(scene, scene.camera.generate_pixel(px, row, sampler.next_2d(), scene.width, scene.height));
    if (need_materials_) tally(scratch.materials, f.hit ? f.material : 0u);
    if (need_objects_) tally(scratch.objects, f.hit ? f.object : 0u);
    if (!f.hit) continue;
    ++hits;
    albedo += glm::dvec3(f.albedo);
    normal += glm::dvec3(f.n);
    const glm::dvec3 p(f.p);
    position += p;
    depth += glm::dot(p - eye, forward);
  }
  const double inv_n = 1.0 / double(n);
  if (albedo_[0])
    for (int c = 0; c < 3; ++c) albedo_[c][i] = float(albedo[c] * inv_n);
  if (normal_[0])
    for (int c = 0; c < 3; ++c) normal_[c][i] = float(normal[c] * inv_n);
  if (position_[0])
    for (int c = 0; c < 3; ++c)
      position_[c][i] = hits ? float(scene.frame_origin[c] + position[c] / double(hits)) : 0.f;
  if (depth_) depth_[i] = hits ? float(depth / double(hits)) : std::numeric_limits<float>::infinity();
  if (material_id_) material_id_[i] = float(most_covering(scratch.materials));
  if (object_id_) object_id_[i] = float(most_covering(scratch.objects));
  if (crypto_material_[0]) write_crypto(crypto_material_, i, scratch.materials, material_crypto_, n, scratch.crypto);
  if (crypto_object_[0]) write_crypto(crypto_object_, i, scratch.objects, object_crypto_, n, scratch.crypto);
}

std::map<std::string, std::string> layer_metadata(const Scene& scene, LayerSet layers) {
  std::map<std::string, std::string> out;
  if (layers.has(Layer::kCryptoMaterial)) {
    const std::vector<std::string> names(scene.material_names.begin() + (scene.material_names.empty() ? 0 : 1),
                                         scene.material_names.end());
    out.merge(cryptomatte_metadata(kLayerNames[size_t(Layer::kCryptoMaterial)], names));
  }
  if (layers.has(Layer::kCryptoObject))
    out.merge(cryptomatte_metadata(kLayerNames[size_t(Layer::kCryptoObject)], scene.object_names));
  return out;
}

std::vector<ExrPart> layer_parts(const Image& img) {
  std::vector<ExrPart> parts;
  for (int i = 0; i < kLayerCount; ++i) {
    std::vector<std::string> channels = layer_channels(Layer(i));
    if (!img.extra.count(channels.front())) continue;
    std::erase_if(channels, [&](const std::string& c) { return !img.extra.count(c); });
    parts.push_back({std::string(kLayerNames[i]), std::move(channels)});
  }
  return parts;
}

}  // namespace tessera
