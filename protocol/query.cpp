#include "protocol/query.h"

#include "core/util/enum_names.h"

#include "protocol/errors.h"
#include "protocol/events.h"

#include <algorithm>
#include <cctype>
#include <charconv>
#include <limits>
#include <span>
#include <stdexcept>
#include <vector>

namespace tessera::protocol {

namespace {

int hex_digit(char c) {
  if (c >= '0' && c <= '9') return c - '0';
  if (c >= 'a' && c <= 'f') return c - 'a' + 10;
  if (c >= 'A' && c <= 'F') return c - 'A' + 10;
  return -1;
}

// Percent-decoding ('+' is a space, as in HTML forms).
std::string decode(std::string_view s) {
  std::string out;
  for (size_t i = 0; i < s.size(); ++i) {
    if (s[i] == '+') {
      out += ' ';
    } else if (s[i] == '%') {
      const int hi = i + 2 < s.size() ? hex_digit(s[i + 1]) : -1;
      const int lo = i + 2 < s.size() ? hex_digit(s[i + 2]) : -1;
      if (hi < 0 || lo < 0)
        throw ProtocolError("query string: bad percent-escape in '" + std::string(s) + "'");
      if (hi < 2) throw ProtocolError("query string: a control character (%" + std::string(s.substr(i + 1, 2)) + ") in '" +
                                      std::string(s) + "'");
      out += char(hi * 16 + lo);
      i += 2;
    } else {
      out += s[i];
    }
  }
  return out;
}

std::string encode(std::string_view s) {
  static const char* hex = "0123456789ABCDEF";
  std::string out;
  for (const char c : s) {
    if (std::isalnum(static_cast<unsigned char>(c)) || c == '-' || c == '_' || c == '.' || c == '~' || c == ',') {
      out += c;
    } else {
      out += '%';
      out += hex[static_cast<unsigned char>(c) >> 4];
      out += hex[static_cast<unsigned char>(c) & 15];
    }
  }
  return out;
}

std::string known_list(std::span<const char* const> known) {
  std::string s;
  for (const char* k : known) {
    if (!s.empty()) s += ", ";
    s += k;
  }
  return s.empty() ? "none" : s;
}

// The items of a comma-separated value ("a,b" -> a, b; "" -> one empty item).
std::vector<std::string> comma_items(std::string_view value) {
  std::vector<std::string> items;
  while (true) {
    const size_t comma = value.find(',');
    items.emplace_back(value.substr(0, comma));
    if (comma == std::string_view::npos) return items;
    value = value.substr(comma + 1);
  }
}

}  // namespace

std::map<std::string, std::string> query_params(std::string_view target, std::initializer_list<const char*> known) {
  std::map<std::string, std::string> out;
  const size_t q = target.find('?');
  if (q == std::string_view::npos) return out;
  std::string_view rest = target.substr(q + 1);
  while (!rest.empty()) {
    const size_t amp = rest.find('&');
    const std::string_view pair = rest.substr(0, amp);
    rest = amp == std::string_view::npos ? std::string_view() : rest.substr(amp + 1);
    if (pair.empty()) continue;
    const size_t eq = pair.find('=');
    const std::string key = decode(pair.substr(0, eq));
    const std::string value = eq == std::string_view::npos ? std::string() : decode(pair.substr(eq + 1));
    if (std::none_of(known.begin(), known.end(), [&](const char* k) { return key == k; }))
      throw ProtocolError("unknown query parameter '" + key + "' (allowed: " +
                          known_list({known.begin(), known.size()}) + ")");
    if (!out.emplace(key, value).second) throw ProtocolError("query parameter '" + key + "' is given more than once");
  }
  return out;
}

JobListQuery parse_job_list_query(std::string_view target) {
  const auto params = query_params(target, {"state", "limit", "after", "owner"});
  JobListQuery q;
  if (const auto it = params.find("state"); it != params.end()) {
    for (const std::string& name : comma_items(it->second)) {
      try {
        const JobState s = job_state_from_string(name);
        if (std::find(q.states.begin(), q.states.end(), s) == q.states.end()) q.states.push_back(s);
      } catch (const std::invalid_argument&) {
        std::string all;
        for (const JobState s : kAllJobStates) {
          if (!all.empty()) all += ", ";
          all += to_string(s);
        }
        throw ProtocolError("state: '" + name + "' is not a job state (one or more of " + all + ", comma-separated)");
      }
    }
  }
  if (const auto it = params.find("limit"); it != params.end()) {
    const std::string& v = it->second;
    size_t n = 0;
    const auto [ptr, ec] = std::from_chars(v.data(), v.data() + v.size(), n);
    if (v.empty() || ec != std::errc() || ptr != v.data() + v.size() || n < 1 || n > kMaxJobListLimit)
      throw ProtocolError("limit: '" + v + "' is not a whole number from 1 to " + std::to_string(kMaxJobListLimit));
    q.limit = n;
  }
  if (const auto it = params.find("after"); it != params.end()) {
    if (it->second.empty()) throw ProtocolError("after: empty (give the \"next\" of the previous page or a job id)");
    q.after = it->second;
  }
  if (const auto it = params.find("owner"); it != params.end()) {
    if (it->second.empty()) throw ProtocolError("owner: empty (give a user name)");
    q.owner = it->second;
  }
  return q;
}

namespace {
// A whole-number query value from lo to hi; throws ProtocolError naming the key.
int64_t query_number(const std::string& key, const std::string& v, int64_t lo, int64_t hi) {
  int64_t n = 0;
  const auto [ptr, ec] = std::from_chars(v.data(), v.data() + v.size(), n);
  if (v.empty() || ec != std::errc() || ptr != v.data() + v.size() || n < lo || n > hi)
    throw ProtocolError(key + ": '" + v + "' is not a whole number from " + std::to_string(lo) + " to " +
                        std::to_string(hi));
  return n;
}
}  // namespace

FrameListQuery parse_frame_list_query(std::string_view target) {
  const auto params = query_params(target, {"limit", "after"});
  FrameListQuery q;
  const auto number = query_number;
  if (const auto it = params.find("limit"); it != params.end())
    q.limit = size_t(number("limit", it->second, 1, int64_t(kMaxJobListLimit)));
  if (const auto it = params.find("after"); it != params.end())
    q.after = number("after", it->second, -1, kMaxFrameNumber);
  return q;
}

std::string FrameListQuery::to_query() const {
  std::string q;
  if (after) q += "?after=" + std::to_string(*after);
  if (limit > 0) q += (q.empty() ? "?limit=" : "&limit=") + std::to_string(limit);
  return q;
}

AuditQuery parse_audit_query(std::string_view target) {
  const auto params = query_params(target, {"before", "limit", "user"});
  AuditQuery q;
  if (const auto it = params.find("before"); it != params.end())
    q.before = query_number("before", it->second, 1, std::numeric_limits<int64_t>::max());
  if (const auto it = params.find("limit"); it != params.end())
    q.limit = size_t(query_number("limit", it->second, 1, int64_t(kMaxJobListLimit)));
  if (const auto it = params.find("user"); it != params.end()) {
    if (it->second.empty()) throw ProtocolError("user: empty (give a user name)");
    q.user = it->second;
  }
  return q;
}

std::string AuditQuery::to_query() const {
  std::string q;
  const auto add = [&](const char* key, const std::string& value) { q += (q.empty() ? "?" : "&") + std::string(key) + "=" + encode(value); };
  if (before) add("before", std::to_string(*before));
  if (limit != AuditQuery{}.limit) add("limit", std::to_string(limit));
  if (!user.empty()) add("user", user);
  return q;
}

std::optional<Layer> parse_preview_query(std::string_view target) {
  const auto params = query_params(target, {"layer"});
  const auto it = params.find("layer");
  if (it == params.end()) return std::nullopt;
  const std::optional<Layer> l = enum_from_name<Layer>(it->second, kLayerNames);
  if (!l) {
    std::string list;
    for (std::string_view n : kLayerNames) list += (list.empty() ? "" : ", ") + std::string(n);
    throw ProtocolError("layer: '" + it->second + "' is not one of " + list);
  }
  return l;
}

bool parse_purge_query(std::string_view target) {
  const auto params = query_params(target, {"purge"});
  const auto it = params.find("purge");
  if (it == params.end() || it->second == "false") return false;
  if (it->second == "true") return true;
  throw ProtocolError("purge: '" + it->second + "' is not true or false");
}

std::string JobListQuery::to_query() const {
  std::string q;
  const auto add = [&](const char* key, const std::string& value) {
    q += q.empty() ? '?' : '&';
    q += key;
    q += '=';
    q += encode(value);
  };
  if (!states.empty()) {
    std::string s;
    for (const JobState st : states) {
      if (!s.empty()) s += ',';
      s += to_string(st);
    }
    add("state", s);
  }
  if (limit > 0) add("limit", std::to_string(limit));
  if (!after.empty()) add("after", after);
  if (!owner.empty()) add("owner", owner);
  return q;
}

std::set<std::string> parse_event_filter(std::string_view target) {
  const auto params = query_params(target, {"only"});
  std::set<std::string> only;
  const auto it = params.find("only");
  if (it == params.end()) return only;
  for (const std::string& name : comma_items(it->second)) {
    if (std::none_of(std::begin(events::kFilterable), std::end(events::kFilterable), [&](const char* e) { return name == e; }))
      throw ProtocolError("only: '" + name + "' is not an event (one or more of " + known_list(events::kFilterable) +
                          ", comma-separated)");
    only.insert(name);
  }
  return only;
}

std::string event_filter_query(const std::set<std::string>& only) {
  std::string q;
  for (const std::string& name : only) q += (q.empty() ? "?only=" : ",") + name;
  return q;
}

}  // namespace tessera::protocol
