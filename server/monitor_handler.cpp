#include "server/monitor_handler.h"

#include "protocol/messages.h"
#include "server/monitor_assets.h"
#include "server/scheduler.h"

#include <nlohmann/json.hpp>

#include <algorithm>
#include <string>
#include <string_view>
#include <utility>

namespace tessera::server {

namespace {

constexpr std::string_view kCapabilities = "capabilities.json";
constexpr std::string_view kProtocolModule = "protocol.js";

// Scripts, styles and images only from this origin; no inline code, no framing, no forms posting elsewhere.
// Preview images arrive through fetch() with the bearer token and are shown as blob: URLs.
constexpr const char* kContentSecurityPolicy =
    "default-src 'none'; script-src 'self'; style-src 'self'; img-src 'self' blob:; connect-src 'self'; "
    "base-uri 'none'; form-action 'none'; frame-ancestors 'none'";

std::string_view path_of(std::string_view target) { return target.substr(0, target.find('?')); }

const char* content_type(std::string_view path) {
  if (path.ends_with(".html")) return "text/html; charset=utf-8";
  if (path.ends_with(".js")) return "text/javascript; charset=utf-8";
  if (path.ends_with(".css")) return "text/css; charset=utf-8";
  if (path.ends_with(".svg")) return "image/svg+xml";
  if (path.ends_with(".json")) return "application/json";
  return "application/octet-stream";
}

// The page's ES module of the protocol's tables: every route's pattern by name, the job states (and those a job ends
// in) and the tile states.
std::string protocol_module() {
  nlohmann::json routes = nlohmann::json::object(), job_states = nlohmann::json::array(),
                 final_states = nlohmann::json::array(), tile_states = nlohmann::json::array();
  for (const protocol::RouteSpec& r : protocol::route_table()) routes[std::string(r.name)] = r.pattern;
  for (protocol::JobState s : protocol::kAllJobStates) {
    job_states.push_back(protocol::to_string(s));
    if (protocol::is_final(s)) final_states.push_back(protocol::to_string(s));
  }
  for (TileState s : {TileState::pending, TileState::leased, TileState::merging, TileState::done})
    tile_states.push_back(to_string(s));
  return "// The coordinator's protocol tables (protocol/routes.h, protocol/job.h), as this coordinator serves them.\n"
         "export const ROUTES = " + routes.dump() + ";\n"
         "export const JOB_STATES = " + job_states.dump() + ";\n"
         "export const FINAL_JOB_STATES = " + final_states.dump() + ";\n"
         "export const TILE_STATES = " + tile_states.dump() + ";\n";
}

void set_monitor_headers(HttpResponse& res) {
  res.set("Content-Security-Policy", kContentSecurityPolicy);
  res.set("X-Content-Type-Options", "nosniff");
  res.set(http::field::x_frame_options, "DENY");
  res.set("Referrer-Policy", "no-referrer");
}

HttpResponse monitor_response(http::status status, std::string body, const char* type, unsigned version) {
  HttpResponse res{status, version};
  res.set(http::field::content_type, type);
  res.body() = std::move(body);
  set_monitor_headers(res);
  res.prepare_payload();
  return res;
}

// The 405 for a monitor request that is not a GET.
HttpResponse not_get(const http::request_header<>& header) {
  HttpResponse res = json_error(http::status::method_not_allowed,
                                std::string(header.method_string()) + " is not allowed on the monitor (allowed: GET)",
                                header.version());
  res.set(http::field::allow, "GET");
  return res;
}

}  // namespace

MonitorHandler::MonitorHandler(RoutedHandler& api, bool tokens_required) : api_(api), tokens_required_(tokens_required) {}

std::size_t MonitorHandler::routed_body_limit(const http::request_header<>& header, const Route& route) {
  return route.monitor ? 0 : api_.routed_body_limit(header, route);
}

std::optional<HttpResponse> MonitorHandler::routed_early_response(const http::request_header<>& header,
                                                                  const Route& route) noexcept {
  // The page itself needs no token; anything but GET on it is refused before its body is read.
  if (route.monitor) return header.method() == http::verb::get ? std::nullopt : std::optional(not_get(header));
  return api_.routed_early_response(header, route);
}

void MonitorHandler::handle_routed(HttpRequest&& req, const Route& route, Reply done) noexcept {
  if (!route.monitor) return api_.handle_routed(std::move(req), route, std::move(done));
  done({serve(req), nullptr});
}

HttpResponse MonitorHandler::serve(const HttpRequest& req) const {
  try {
    if (req.method() != http::verb::get) return not_get(req.base());
    const std::string_view path = path_of(req.target());
    if (path == std::string(kMonitorPrefix) + std::string(kCapabilities)) return capabilities(req);
    if (path == std::string(kMonitorPrefix) + std::string(kProtocolModule)) {
      HttpResponse res = monitor_response(http::status::ok, protocol_module(), content_type(path), req.version());
      res.set(http::field::cache_control, "no-cache");
      return res;
    }
    return serve_static(req);
  } catch (const std::exception& e) {
    return json_error(http::status::internal_server_error, std::string("internal error: ") + e.what(), req.version());
  }
}

HttpResponse MonitorHandler::serve_static(const HttpRequest& req) const {
  const std::string_view path = path_of(req.target());
  const std::string_view name = path == "/" ? std::string_view("index.html") : path.substr(kMonitorPrefix.size());
  const auto files = monitor_assets();
  const auto it = std::find_if(files.begin(), files.end(), [&](const EmbeddedFile& f) { return f.path == name; });
  if (it == files.end())
    return json_error(http::status::not_found, "no such monitor file: " + std::string(path), req.version());
  const bool fresh = req[http::field::if_none_match] == it->etag;
  HttpResponse res = monitor_response(fresh ? http::status::not_modified : http::status::ok,
                                      fresh ? std::string() : std::string(it->bytes), content_type(name), req.version());
  res.set(http::field::etag, it->etag);
  res.set(http::field::cache_control, "no-cache");  // revalidate: a new binary may carry new files
  return res;
}

HttpResponse MonitorHandler::capabilities(const HttpRequest& req) const {
  HttpResponse res = monitor_response(http::status::ok, nlohmann::json(protocol::capabilities(tokens_required_)).dump(),
                                      "application/json", req.version());
  res.set(http::field::cache_control, "no-store");
  return res;
}

}  // namespace tessera::server
