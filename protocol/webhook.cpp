#include "protocol/webhook.h"

#include "protocol/json_fields.h"

#include <nlohmann/json.hpp>

namespace tessera::protocol {

using nlohmann::json;

void to_json(json& j, const WebhookDelivery& d) {
  j = {{"id", d.id},           {"url", d.url},         {"event", d.event},
       {"job", d.job},         {"state", d.state},     {"attempts", d.attempts},
       {"created_ms", d.created_ms}, {"next_ms", optional_json(d.next_ms)},
       {"last_status", optional_json(d.last_status)}, {"last_error", optional_json(d.last_error)}};
}

void from_json(const json& j, WebhookDelivery& d) {
  constexpr const char* kMsg = "webhook delivery";
  d.id = answer_field<std::string>(j, "id", kMsg);
  d.url = answer_field<std::string>(j, "url", kMsg);
  d.event = answer_field<std::string>(j, "event", kMsg);
  d.job = answer_field_or<std::string>(j, "job", kMsg, "");
  d.state = answer_field<std::string>(j, "state", kMsg);
  d.attempts = answer_field_or<int64_t>(j, "attempts", kMsg, 0);
  d.created_ms = answer_field_or<int64_t>(j, "created_ms", kMsg, 0);
  if (j.contains("next_ms") && !j["next_ms"].is_null()) d.next_ms = answer_field<int64_t>(j, "next_ms", kMsg);
  if (j.contains("last_status") && !j["last_status"].is_null()) d.last_status = answer_field<int>(j, "last_status", kMsg);
  if (j.contains("last_error") && !j["last_error"].is_null())
    d.last_error = answer_field<std::string>(j, "last_error", kMsg);
}

void to_json(json& j, const WebhookDeliveryList& l) { j = {{"deliveries", l.deliveries}}; }

void from_json(const json& j, WebhookDeliveryList& l) {
  l.deliveries = answer_field<std::vector<WebhookDelivery>>(j, "deliveries", "webhook deliveries");
}

}  // namespace tessera::protocol
