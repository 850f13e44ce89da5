// Sequences (docs/protocol.md, "Sequences"): a job that renders many frames, each frame a full scene rendered and
// merged as a one-image job is. The order its frames are leased in, its frames' counts by state, and the frame
// numbers a request names.
#pragma once

#include "core/util/enum_names.h"

#include <nlohmann/json_fwd.hpp>

#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

namespace tessera::protocol {

/// The order a sequence's tiles are leased in.
enum class FrameOrder {
  in_order,  ///< The earliest unfinished frame's tiles first: frames finish one after another.
  any,       ///< Each worker stays on a frame of its own (it loads each scene once); frames finish in any order.
};
/// The protocol's name of each frame order, in declaration order.
inline constexpr std::string_view kFrameOrderNames[] = {"in_order", "any"};
/// The protocol's name of a frame order.
inline const char* to_string(FrameOrder o) { return enum_c_name(o, kFrameOrderNames); }
/// Parses a frame order name; throws std::invalid_argument for unknown names.
inline FrameOrder frame_order_from_string(std::string_view s) {
  return enum_from_name_or_throw<FrameOrder>(s, kFrameOrderNames, "frame order");
}

/// The most frames one sequence may have unless the coordinator is told otherwise (`serve --max-job-frames`).
inline constexpr int64_t kDefaultMaxJobFrames = 100'000;
/// The largest frame number a sequence may use.
inline constexpr int64_t kMaxFrameNumber = 999'999'999;

/// The id of frame `number`'s own job in the sequence `sequence` ("j-7.f12").
inline std::string frame_job_id(std::string_view sequence, int64_t number) {
  return std::string(sequence) + ".f" + std::to_string(number);
}

/// A sequence's frames by the state of each frame (a frame is a job of its own; see JobStatus::sequence).
struct FrameCounts {
  int64_t total = 0;      ///< Frames in the sequence.
  int64_t queued = 0;     ///< Not started.
  int64_t running = 0;    ///< Started, not ended.
  int64_t paused = 0;     ///< Paused.
  int64_t done = 0;       ///< Result written.
  int64_t failed = 0;     ///< Failed (the other frames go on).
  int64_t cancelled = 0;  ///< Cancelled.
  int64_t waiting = 0;    ///< Waiting for a dependency.
  int64_t blocked = 0;    ///< Blocked by a dependency that failed or was cancelled.
  int64_t first = 0;      ///< The lowest frame number.
  int64_t last = 0;       ///< The highest frame number.
};
void to_json(nlohmann::json& j, const FrameCounts& c);
void from_json(const nlohmann::json& j, FrameCounts& c);

/// The body of POST /v1/jobs/{id}/retry: which frames of a sequence to retry (absent: the whole job).
struct RetryRequest {
  std::vector<int64_t> frames;  ///< Frame numbers (empty: every failed or cancelled frame, or the one-image job).
};
void to_json(nlohmann::json& j, const RetryRequest& r);
/// Parses a retry body (empty, {}, or {"frames": [N, ...]} with at most kDefaultMaxJobFrames numbers); throws
/// ProtocolError with the sentence answered (400).
RetryRequest parse_retry_request(const std::string& body);

}  // namespace tessera::protocol
