#include "server/webhook_url.h"

#include <algorithm>
#include <cctype>
#include <stdexcept>

namespace tessera::server {

namespace {

std::string lower(std::string s) {
  std::transform(s.begin(), s.end(), s.begin(), [](unsigned char c) { return char(std::tolower(c)); });
  return s;
}

}  // namespace

WebhookUrl parse_webhook_url(std::string_view url) {
  const auto refuse = [&](const std::string& why) {
    return std::invalid_argument("webhook address '" + std::string(url) + "' " + why);
  };
  WebhookUrl u;
  u.text = std::string(url);
  for (const char c : url)
    if (static_cast<unsigned char>(c) <= 0x20 || c == 0x7f) throw refuse("contains a space or control character");
  std::string_view rest;
  if (url.rfind("http://", 0) == 0) {
    rest = url.substr(7);
  } else if (url.rfind("https://", 0) == 0) {
    u.https = true;
    rest = url.substr(8);
  } else {
    throw refuse("is not an http:// or https:// URL");
  }
  if (url.find('#') != std::string_view::npos) throw refuse("has a fragment ('#')");
  const size_t slash = rest.find_first_of("/?");
  const std::string_view authority = rest.substr(0, slash);
  u.target = slash == std::string_view::npos ? "/" : std::string(rest.substr(slash));
  if (u.target.front() == '?') u.target = "/" + u.target;
  if (authority.find('@') != std::string_view::npos) throw refuse("names a user ('@'): credentials go in no URL");
  std::string_view host = authority, port;
  if (!authority.empty() && authority.front() == '[') {
    const size_t close = authority.find(']');
    if (close == std::string_view::npos) throw refuse("has an unclosed '['");
    host = authority.substr(1, close - 1);
    const std::string_view after = authority.substr(close + 1);
    if (!after.empty()) {
      if (after.front() != ':') throw refuse("has text after its IPv6 address");
      port = after.substr(1);
    }
  } else if (const size_t colon = authority.rfind(':'); colon != std::string_view::npos) {
    host = authority.substr(0, colon);
    port = authority.substr(colon + 1);
  }
  if (host.empty()) throw refuse("has no host");
  u.host = lower(std::string(host));
  if (port.empty()) {
    u.port = u.https ? "443" : "80";
  } else {
    if (port.size() > 5 || !std::all_of(port.begin(), port.end(), [](char c) { return std::isdigit(static_cast<unsigned char>(c)); }) ||
        std::stoi(std::string(port)) < 1 || std::stoi(std::string(port)) > 65535)
      throw refuse("has no valid port (1 to 65535)");
    u.port = std::to_string(std::stoi(std::string(port)));
  }
  return u;
}

WebhookAllowList::WebhookAllowList(const std::vector<std::string>& entries) {
  for (const std::string& e : entries) entries_.push_back(parse_webhook_url(e));
}

void WebhookAllowList::check(std::string_view url) const {
  const WebhookUrl u = parse_webhook_url(url);
  for (const WebhookUrl& a : entries_)
    if (a.https == u.https && a.host == u.host && a.port == u.port && u.target.rfind(a.target, 0) == 0) return;
  throw std::invalid_argument(
      "webhook address '" + std::string(url) + "' is not allowed: " +
      (entries_.empty() ? std::string("this coordinator allows no per-job webhook (serve --webhook-allow)")
                        : "it matches no address of serve --webhook-allow"));
}

}  // namespace tessera::server
