// Cryptomatte ids and metadata, as the public Cryptomatte specification defines them: a name's id is the
// MurmurHash3_x86_32 (seed 0) of its bytes, stored in a float channel bit for bit (its exponent nudged off 0 and 255
// so that it is never a denormal, an infinity or a NaN); each pixel holds (id, coverage) pairs by falling coverage in
// channels <name>00.R/G/B/A, <name>01..., and the header names the layer, its hash, its conversion and its manifest
// (names to hex ids) under cryptomatte/<key>/, the key being the first 7 hex digits of the layer name's hash.
#pragma once

#include <cstdint>
#include <map>
#include <string>
#include <string_view>
#include <vector>

namespace tessera {

/// MurmurHash3_x86_32 of `bytes` with seed 0.
uint32_t murmur3_32(std::string_view bytes);

/// The Cryptomatte id of `name`: its hash with bit 23 flipped when the exponent bits are all 0 or all 1.
uint32_t cryptomatte_id(std::string_view name);

/// The id as the float stored in the id channels (the same bits).
float cryptomatte_float(uint32_t id);

/// The header attributes of a Cryptomatte layer called `layer` over `names` (duplicates share one entry):
/// cryptomatte/<key>/name, /hash ("MurmurHash3_32"), /conversion ("uint32_to_float32") and /manifest (a JSON object
/// from each name to its id as 8 lowercase hex digits).
std::map<std::string, std::string> cryptomatte_metadata(std::string_view layer, const std::vector<std::string>& names);

}  // namespace tessera
