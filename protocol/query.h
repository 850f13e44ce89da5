// Query strings of request targets: GET /v1/jobs?state=S[,S]&limit=N&after=CURSOR, DELETE /v1/jobs/{id}?purge=B,
// GET /v1/jobs/{id}/preview.png?layer=NAME and GET /v1/events?only=NAME[,NAME].
// Parsers refuse unknown keys, repeated keys and bad values with a ProtocolError (400) naming them.
#pragma once

#include "core/render/layers.h"
#include "protocol/job.h"

#include <cstddef>
#include <initializer_list>
#include <map>
#include <optional>
#include <set>
#include <string>
#include <string_view>
#include <vector>

namespace tessera::protocol {

/// The largest `limit` of a job listing.
inline constexpr size_t kMaxJobListLimit = 10'000;

/// What a job listing asks for.
struct JobListQuery {
  std::vector<JobState> states;  ///< Wanted states; empty: every state.
  size_t limit = 0;              ///< Most jobs in one answer; 0: all.
  std::string after;             ///< The `next` cursor of the previous page, or the last job id seen; "": newest.
  std::string owner;             ///< Only this user's jobs; "": everyone's.
  /// The query string for a request target ("" when everything is at its default, else "?...").
  std::string to_query() const;
};

/// What a page of a sequence's frames asks for: GET /v1/jobs/{id}/frames?after=N&limit=M.
struct FrameListQuery {
  std::optional<int64_t> after;  ///< Only frames numbered above this.
  size_t limit = 0;              ///< Most frames in one answer; 0: all.
  /// The query string for a request target ("" when everything is at its default, else "?...").
  std::string to_query() const;
};

/// The decoded key=value pairs of the target's query string (after '?'); throws ProtocolError for keys outside
/// `known`, repeated keys and bad percent-escapes.
std::map<std::string, std::string> query_params(std::string_view target, std::initializer_list<const char*> known);
/// Parses the query of GET /v1/jobs; throws ProtocolError with the sentence answered (400).
JobListQuery parse_job_list_query(std::string_view target);
/// What GET /v1/audit asks for: ?before=ID&limit=N&user=NAME.
struct AuditQuery {
  std::optional<int64_t> before;  ///< Only entries numbered below this.
  size_t limit = 100;             ///< Most entries in one answer (1 to kMaxJobListLimit).
  std::string user;               ///< Only this user's actions ("" every user's).
  /// The query string for a request target ("" when everything is at its default, else "?...").
  std::string to_query() const;
};
/// Parses the query of GET /v1/audit; throws ProtocolError with the sentence answered (400).
AuditQuery parse_audit_query(std::string_view target);
/// Parses the query of GET /v1/jobs/{id}/frames; throws ProtocolError with the sentence answered (400).
FrameListQuery parse_frame_list_query(std::string_view target);
/// Parses the query of GET /v1/jobs/{id}/preview.png: layer=NAME shows that output layer (core/render/layers.h)
/// instead of the colour; nothing for the colour.
std::optional<Layer> parse_preview_query(std::string_view target);
/// Parses the query of DELETE /v1/jobs/{id}: true for purge=true; false for none or purge=false.
bool parse_purge_query(std::string_view target);
/// Parses the query of GET /v1/events (only=NAME[,NAME]: just those events, and resync); empty: every event.
std::set<std::string> parse_event_filter(std::string_view target);
/// The query string asking for `only` those events ("" for every event).
std::string event_filter_query(const std::set<std::string>& only);

}  // namespace tessera::protocol
