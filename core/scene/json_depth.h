// How deeply a JSON text nests, measured before it is parsed: the first check on any scene or request body.
#pragma once

#include <string_view>

namespace tessera {

/// Deepest nesting of arrays and objects in a JSON text (brackets inside strings do not count); scans without
/// recursion, so callers can refuse deep input before parsing it (printing or copying it would recurse).
int json_nesting_depth(std::string_view text);

/// Nesting depth load_scene_text accepts (the format needs 5).
inline constexpr int kMaxSceneJsonDepth = 64;

}  // namespace tessera
