// A webhook's address: parsed strictly (http or https, a host, no user name or fragment), and matched against the
// operator's allow-list (`serve --webhook-allow`), so that a submission cannot make the coordinator call any host.
#pragma once

#include <string>
#include <string_view>
#include <vector>

namespace tessera::server {

/// A parsed webhook address.
struct WebhookUrl {
  bool https = false;      ///< https (else http).
  std::string host;        ///< Host name or address, lowercase (an IPv6 address without brackets).
  std::string port;        ///< Port, always set (80 or 443 by default).
  std::string target;      ///< Path and query, at least "/".
  std::string text;        ///< The address as given.
};

/// Parses an address; throws std::invalid_argument with a sentence naming it.
WebhookUrl parse_webhook_url(std::string_view url);

/// The addresses submissions may name: each entry is an address whose scheme, host and port must be equal and whose
/// path must begin the submitted one's.
class WebhookAllowList {
 public:
  WebhookAllowList() = default;
  /// From `serve --webhook-allow` entries; throws std::invalid_argument for an entry that is no address.
  explicit WebhookAllowList(const std::vector<std::string>& entries);
  /// Throws std::invalid_argument with the sentence answered when `url` is unparsable or outside the list (an empty
  /// list allows nothing).
  void check(std::string_view url) const;
  /// True when it holds no entry.
  bool empty() const { return entries_.empty(); }

 private:
  std::vector<WebhookUrl> entries_;
};

}  // namespace tessera::server
