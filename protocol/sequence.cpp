#include "protocol/sequence.h"

#include "protocol/json_fields.h"

#include <nlohmann/json.hpp>

#include <string>

namespace tessera::protocol {

using nlohmann::json;

void to_json(json& j, const FrameCounts& c) {
  j = {{"total", c.total},   {"queued", c.queued}, {"running", c.running},     {"paused", c.paused},
       {"done", c.done},     {"failed", c.failed}, {"cancelled", c.cancelled}, {"waiting", c.waiting},
       {"blocked", c.blocked}, {"first", c.first},   {"last", c.last}};
}

void from_json(const json& j, FrameCounts& c) {
  constexpr const char* kMsg = "job frames";
  c.total = answer_field<int64_t>(j, "total", kMsg);
  c.queued = answer_field_or<int64_t>(j, "queued", kMsg, 0);
  c.running = answer_field_or<int64_t>(j, "running", kMsg, 0);
  c.paused = answer_field_or<int64_t>(j, "paused", kMsg, 0);
  c.done = answer_field_or<int64_t>(j, "done", kMsg, 0);
  c.failed = answer_field_or<int64_t>(j, "failed", kMsg, 0);
  c.cancelled = answer_field_or<int64_t>(j, "cancelled", kMsg, 0);
  c.waiting = answer_field_or<int64_t>(j, "waiting", kMsg, 0);
  c.blocked = answer_field_or<int64_t>(j, "blocked", kMsg, 0);
  c.first = answer_field_or<int64_t>(j, "first", kMsg, 0);
  c.last = answer_field_or<int64_t>(j, "last", kMsg, 0);
}

void to_json(json& j, const RetryRequest& r) {
  j = json::object();
  if (!r.frames.empty()) j["frames"] = r.frames;
}

RetryRequest parse_retry_request(const std::string& body) {
  const json j = parse_request_object(body, {"frames"}, true);
  RetryRequest r;
  if (!j.contains("frames")) return r;
  const json& f = j["frames"];
  if (!f.is_array() || f.empty() || f.size() > size_t(kDefaultMaxJobFrames))
    throw ProtocolError("'frames' must be a non-empty array of at most " + std::to_string(kDefaultMaxJobFrames) +
                        " frame numbers");
  for (size_t i = 0; i < f.size(); ++i) {
    if (!f[i].is_number_integer() || f[i].get<int64_t>() < 0 || f[i].get<int64_t>() > kMaxFrameNumber)
      throw ProtocolError("frames[" + std::to_string(i) + "] must be a frame number from 0 to " +
                          std::to_string(kMaxFrameNumber) + " (got " + f[i].dump() + ")");
    r.frames.push_back(f[i].get<int64_t>());
  }
  return r;
}

}  // namespace tessera::protocol
