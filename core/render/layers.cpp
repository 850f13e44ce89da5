#include "core/render/layers.h"

#include "core/util/enum_names.h"

#include <stdexcept>

namespace tessera {

std::vector<Layer> LayerSet::list() const {
  std::vector<Layer> out;
  for (int i = 0; i < kLayerCount; ++i)
    if (has(Layer(i))) out.push_back(Layer(i));
  return out;
}

LayerSet parse_layers(std::string_view list) {
  LayerSet set;
  size_t start = 0;
  while (start <= list.size() && !list.empty()) {
    const size_t comma = list.find(',', start);
    const std::string_view name = list.substr(start, comma == std::string_view::npos ? list.npos : comma - start);
    const std::optional<Layer> l = enum_from_name<Layer>(name, kLayerNames);
    if (!l) {
      std::string known;
      for (const std::string_view n : kLayerNames) known += (known.empty() ? "" : ", ") + std::string(n);
      throw std::invalid_argument("unknown layer '" + std::string(name) + "' (known: " + known + ")");
    }
    set.add(*l);
    if (comma == std::string_view::npos) break;
    start = comma + 1;
  }
  return set;
}

std::string layers_to_string(LayerSet layers) {
  std::string out;
  for (const Layer l : layers.list()) out += (out.empty() ? "" : ",") + std::string(enum_name(l, kLayerNames));
  return out;
}

std::vector<std::string> layer_channels(Layer layer) {
  switch (layer) {
    case Layer::kAlbedo: return {"albedo.R", "albedo.G", "albedo.B"};
    case Layer::kNormal: return {"N.X", "N.Y", "N.Z"};
    case Layer::kDepth: return {"Z"};
    case Layer::kPosition: return {"P.X", "P.Y", "P.Z"};
    case Layer::kMaterialId: return {"material_id"};
    case Layer::kObjectId: return {"object_id"};
    case Layer::kVariance: return {"variance.R", "variance.G", "variance.B", "samples"};
    case Layer::kCryptoMaterial:
    case Layer::kCryptoObject: {
      std::vector<std::string> out;
      const std::string name(enum_name(layer, kLayerNames));
      for (int g = 0; g < kCryptomatteRanks / 2; ++g)
        for (const char* c : {".R", ".G", ".B", ".A"}) out.push_back(name + "0" + std::to_string(g) + c);
      return out;
    }
  }
  return {};
}

std::vector<std::string> layer_channels(LayerSet layers) {
  std::vector<std::string> out;
  for (const Layer l : layers.list())
    for (std::string& c : layer_channels(l)) out.push_back(std::move(c));
  return out;
}

}  // namespace tessera
