// What differs between two EXR files, for the "bitwise identical" checks of the farm and deploy tests
// (tests/exr_compare.cpp) and their own test (tests/exr_diff_test.cpp).
#pragma once

#include <filesystem>
#include <set>
#include <string>
#include <vector>

namespace tessera::testing {

/// Header attributes that may differ, or be present in one file only, between two renders of the same pixels:
/// how the file is stored (compression, line order, tiling, part bookkeeping) and when, where and by whom it was
/// rendered (times, job id and name, workers, the scene's path, the farm's tile size).
const std::set<std::string>& attributes_allowed_to_differ();

/// Attributes only some writers record (`tessera render` writes its sampling options, the farm's merged result
/// does not): they may be missing from one file, but must be equal when both have them.
const std::set<std::string>& attributes_not_always_written();

/// Every other attribute (the windows, the channel list with each channel's pixel type and sampling, pixel aspect
/// ratio, screen window, tessera:sceneHash, spp, seed, version) must be present in both files with the same type
/// and value.

/// The differences between the EXR files a and b (first part of each): attributes (as above), then the pixels of
/// every channel compared bitwise in the channel's own pixel type. Empty when they are identical. Throws
/// std::exception when a file cannot be read.
std::vector<std::string> exr_differences(const std::filesystem::path& a, const std::filesystem::path& b);

}  // namespace tessera::testing
