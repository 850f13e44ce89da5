#include "protocol/pipeline.h"

#include "protocol/json_fields.h"

#include <nlohmann/json.hpp>

#include <algorithm>
#include <stdexcept>

namespace tessera::protocol {

using nlohmann::json;

void put_pipeline(json& j, const Pipeline& p) {
  if (!p.after.empty()) j["after"] = p.after;
  if (p.per_frame) j["per_frame"] = true;
  if (!p.then.empty()) {
    json steps = json::array();
    for (const Step s : p.then) steps.push_back(to_string(s));
    j["then"] = std::move(steps);
  }
  if (p.fps != kDefaultMovieFps) j["fps"] = p.fps;
  if (!p.notify.empty()) j["notify"] = p.notify;
  if (p.notify_frames) j["notify_frames"] = true;
}

Pipeline request_pipeline(const json& j) {
  Pipeline p;
  if (auto after = request_strings(j, "after", kMaxDependencies)) {
    for (const std::string& id : *after) {
      if (id.empty() || id.size() > kMaxJobIdBytes)
        throw ProtocolError("\"after\" names a job id of " + std::to_string(id.size()) + " bytes; ids have 1 to " +
                            std::to_string(kMaxJobIdBytes));
      if (std::find(p.after.begin(), p.after.end(), id) == p.after.end()) p.after.push_back(id);
    }
  }
  if (j.contains("per_frame")) {
    if (!j["per_frame"].is_boolean())
      throw ProtocolError("'per_frame' must be true or false (got " + j["per_frame"].dump() + ")");
    p.per_frame = j["per_frame"].get<bool>();
    if (p.per_frame && p.after.empty())
      throw ProtocolError("'per_frame' needs 'after': it says how a sequence waits for the jobs it names");
  }
  if (auto then = request_strings(j, "then", std::size(kStepNames))) {
    for (const std::string& name : *then) {
      Step s{};
      try {
        s = step_from_string(name);
      } catch (const std::invalid_argument&) {
        std::string known;
        for (const std::string_view k : kStepNames) known += (known.empty() ? "" : ", ") + std::string(k);
        throw ProtocolError("\"then\" names an unknown step '" + name + "' (the steps are " + known + ")");
      }
      if (std::find(p.then.begin(), p.then.end(), s) != p.then.end())
        throw ProtocolError("\"then\" names the step '" + name + "' twice");
      p.then.push_back(s);
    }
  }
  if (j.contains("notify")) {
    if (!j["notify"].is_string()) throw ProtocolError("'notify' must be a URL string (got " + j["notify"].dump() + ")");
    p.notify = j["notify"].get<std::string>();
    if (p.notify.empty() || p.notify.size() > kMaxWebhookUrlBytes)
      throw ProtocolError("'notify' must be a URL of 1 to " + std::to_string(kMaxWebhookUrlBytes) + " bytes");
  }
  if (j.contains("fps")) {
    p.fps = int(request_int(j, "fps", kDefaultMovieFps, 1, kMaxMovieFps));
    if (std::find(p.then.begin(), p.then.end(), Step::movie) == p.then.end())
      throw ProtocolError("'fps' is the frame rate of the movie step: it needs \"then\" to name movie");
  }
  if (j.contains("notify_frames")) {
    if (!j["notify_frames"].is_boolean())
      throw ProtocolError("'notify_frames' must be true or false (got " + j["notify_frames"].dump() + ")");
    p.notify_frames = j["notify_frames"].get<bool>();
    if (p.notify_frames && p.notify.empty())
      throw ProtocolError("'notify_frames' needs 'notify': each frame done is told to the job's own address");
  }
  return p;
}

void to_json(json& j, const StepOutput& o) {
  j = {{"step", to_string(o.step)}, {"state", o.state}, {"files", o.files}, {"log", o.log}};
}

void from_json(const json& j, StepOutput& o) {
  constexpr const char* kMsg = "step output";
  try {
    o.step = step_from_string(answer_field<std::string>(j, "step", kMsg));
  } catch (const std::invalid_argument& e) {
    throw ProtocolError(std::string(kMsg) + ": " + e.what());
  }
  o.state = answer_field<std::string>(j, "state", kMsg);
  o.files = answer_field_or<std::vector<std::string>>(j, "files", kMsg, {});
  o.log = answer_field_or<std::string>(j, "log", kMsg, "");
}

Pipeline answer_pipeline(const json& j) {
  constexpr const char* kMsg = "job";
  Pipeline p;
  p.after = answer_field_or<std::vector<std::string>>(j, "after", kMsg, {});
  p.per_frame = answer_field_or<bool>(j, "per_frame", kMsg, false);
  for (const std::string& name : answer_field_or<std::vector<std::string>>(j, "then", kMsg, {})) {
    try {
      p.then.push_back(step_from_string(name));
    } catch (const std::invalid_argument& e) {
      throw ProtocolError(std::string(kMsg) + ": " + e.what());
    }
  }
  p.fps = answer_field_or<int>(j, "fps", kMsg, kDefaultMovieFps);
  p.notify = answer_field_or<std::string>(j, "notify", kMsg, "");
  p.notify_frames = answer_field_or<bool>(j, "notify_frames", kMsg, false);
  return p;
}

}  // namespace tessera::protocol
