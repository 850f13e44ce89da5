#include "server/monitor_handler.h"

#include "protocol/routes.h"
#include "server/monitor_assets.h"

#include <nlohmann/json.hpp>

#include <algorithm>
#include <string>
#include <string_view>
#include <utility>

namespace tessera::server {

namespace {

constexpr std::string_view kPrefix = "/monitor/";
constexpr std::string_view kCapabilities = "capabilities.json";

// Scripts, styles and images only from this origin; no inline code, no framing, no forms posting elsewhere.
// Preview images arrive through fetch() with the bearer token and are shown as blob: URLs.
constexpr const char* kContentSecurityPolicy =
    "default-src 'none'; script-src 'self'; style-src 'self'; img-src 'self' blob:; connect-src 'self'; "
    "base-uri 'none'; form-action 'none'; frame-ancestors 'none'";

std::string_view path_of(std::string_view target) { return target.substr(0, target.find('?')); }

bool is_monitor_path(std::string_view path) { return path == "/" || path.starts_with(kPrefix); }

// True when the protocol's route table has `method target` (the page shows the controls it can use).
bool api_has(std::string_view target, http::verb method) {
  const protocol::RouteMatch m = protocol::match_route(target);
  return m.route && std::find(m.route->methods.begin(), m.route->methods.end(), http::to_string(method)) != m.route->methods.end();
}

const char* content_type(std::string_view path) {
  if (path.ends_with(".html")) return "text/html; charset=utf-8";
  if (path.ends_with(".js")) return "text/javascript; charset=utf-8";
  if (path.ends_with(".css")) return "text/css; charset=utf-8";
  if (path.ends_with(".svg")) return "image/svg+xml";
  if (path.ends_with(".json")) return "application/json";
  return "application/octet-stream";
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

}  // namespace

MonitorHandler::MonitorHandler(HttpHandler& api, bool tokens_required) : api_(api), tokens_required_(tokens_required) {}

std::size_t MonitorHandler::body_limit(const http::request_header<>& header) {
  return is_monitor_path(path_of(header.target())) ? 0 : api_.body_limit(header);
}

std::optional<HttpResponse> MonitorHandler::early_response(const http::request_header<>& header) noexcept {
  const std::string_view path = path_of(header.target());
  if (is_monitor_path(path)) return std::nullopt;  // the page itself needs no token
  return api_.early_response(header);
}

HttpResponse MonitorHandler::handle(HttpRequest&& req) noexcept {
  try {
    const std::string_view path = path_of(req.target());
    if (is_monitor_path(path)) {
      if (req.method() != http::verb::get) {
        HttpResponse res = json_error(http::status::method_not_allowed,
                                      std::string(req.method_string()) + " is not allowed on the monitor (allowed: GET)", req.version());
        res.set(http::field::allow, "GET");
        return res;
      }
      if (path == std::string(kPrefix) + std::string(kCapabilities)) return capabilities(req);
      return serve_static(req);
    }
  } catch (const std::exception& e) {
    return json_error(http::status::internal_server_error, std::string("internal error: ") + e.what(), req.version());
  }
  return api_.handle(std::move(req));
}

HttpReply MonitorHandler::reply(HttpRequest&& req) noexcept {
  const std::string_view path = path_of(req.target());
  if (is_monitor_path(path) || path.ends_with("/tiles")) return {handle(std::move(req)), nullptr};
  return api_.reply(std::move(req));
}

void MonitorHandler::handle_async(HttpRequest&& req, Reply done) noexcept {
  const std::string_view path = path_of(req.target());
  if (is_monitor_path(path) || path.ends_with("/tiles")) return done({handle(std::move(req)), nullptr});
  api_.handle_async(std::move(req), std::move(done));
}

HttpResponse MonitorHandler::serve_static(const HttpRequest& req) const {
  const std::string_view path = path_of(req.target());
  const std::string_view name = path == "/" ? std::string_view("index.html") : path.substr(kPrefix.size());
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
  using V = http::verb;
  const nlohmann::json body = {
      {"tokens_required", tokens_required_},
      {"endpoints",
       {{"pause", api_has("/v1/jobs/j/pause", V::post)},
        {"resume", api_has("/v1/jobs/j/resume", V::post)},
        {"retry", api_has("/v1/jobs/j/retry", V::post)},
        {"priority", api_has("/v1/jobs/j", V::patch)},
        {"purge", true},  // DELETE /v1/jobs/{id}?purge=true (the route also cancels, so it cannot be asked)
        {"requeue", api_has("/v1/jobs/j/tiles/0/requeue", V::post)},
        {"workers", api_has("/v1/workers", V::get)},
        {"drain", api_has("/v1/workers/w/drain", V::post)},
        {"events", api_has("/v1/events", V::get)}}}};
  HttpResponse res = monitor_response(http::status::ok, body.dump(), "application/json", req.version());
  res.set(http::field::cache_control, "no-store");
  return res;
}

}  // namespace tessera::server
