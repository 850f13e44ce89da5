#include "server/api.h"

#include <spdlog/spdlog.h>

#include <algorithm>
#include <chrono>
#include <future>
#include <memory>

namespace tessera::server {

using protocol::ApiError;
using protocol::ProtocolError;

Access route_access(RouteId route, http::verb method) {
  for (const protocol::RouteSpec& r : protocol::route_table()) {
    if (r.endpoint != route) continue;
    const protocol::MethodSpec* m = r.method(http::to_string(method));
    return (m ? *m : r.methods.front()).access;  // a method the route does not take: its first method's token
  }
  return Access::client;  // no such route: the strictest answer
}

Api::Api(Scheduler& scheduler, BlobStore& blobs, JobStore& jobs, Metrics& metrics, ClockMs clock, ApiOptions options,
         EventBus& bus, FarmEvents& events, DiskSpace& disk, Background background)
    : metrics_(metrics),
      disk_(disk),
      opt_(options),
      token_check_(opt_.tokens),
      sched_(scheduler),
      lease_waiters_(std::make_unique<LeaseWaiters>()),
      steps_(scheduler, jobs),
      jobs_(scheduler, blobs, jobs, metrics, clock,
            static_cast<const AdmissionLimits&>(opt_),
            events, disk, std::move(background)),
      collector_(jobs_, scheduler, blobs, clock, opt_.retention),
      jobs_handler_(jobs_, collector_),
      tiles_handler_(jobs_),
      leases_handler_(scheduler, jobs_, metrics, clock, events, *lease_waiters_),
      workers_handler_(scheduler, opt_.heartbeat_seconds, opt_.registrations_per_minute, clock, events),
      blobs_handler_(blobs),
      health_handler_(scheduler, metrics, clock, *lease_waiters_, disk),
      events_handler_(bus),
      webhooks_handler_(opt_.webhook_log),
      outputs_handler_(steps_) {
  jobs_.use_steps(&steps_);
  sched_.on_work([w = lease_waiters_.get()] { w->note_work(); });
}

Api::~Api() {
  sched_.on_work({});
  lease_waiters_.reset();  // expires what it holds, answering through the handlers and the transport, which still live
}

bool Api::authenticated(const http::request_header<>& h) noexcept {
  try {
    const std::string_view authorization = h[http::field::authorization];
    return token_check_.authorize(Access::client, authorization).status == AuthDecision::allowed ||
           token_check_.authorize(Access::worker, authorization).status == AuthDecision::allowed;
  } catch (...) {
    return false;
  }
}

std::size_t Api::routed_body_limit(const http::request_header<>&, const Route& route) {
  if (route.method && route.match.endpoint() == RouteId::blob && route.method->name == "PUT") return opt_.blob_limit;
  if (route.method && route.match.endpoint() == RouteId::lease_result) return opt_.result_limit;  // PUT only
  return opt_.json_limit;
}

std::optional<HttpResponse> Api::check_access(const Route& route, const http::request_header<>& h) {
  const AuthDecision d = token_check_.authorize(route.method->access, h[http::field::authorization]);
  if (d.status == AuthDecision::allowed) return std::nullopt;
  const bool forbidden = d.status == AuthDecision::wrong_role;
  HttpResponse res = json_error(forbidden ? http::status::forbidden : http::status::unauthorized, d.reason, h.version());
  if (!forbidden)
    res.set(http::field::www_authenticate,
            d.status == AuthDecision::missing ? "Bearer realm=\"tessera\"" : "Bearer realm=\"tessera\", error=\"invalid_token\"");
  // The reason names roles, never the presented or configured token; a flood of refusals logs 10 lines a minute.
  uint64_t left_out = 0;
  if (refusal_log_.allow(left_out))
    spdlog::warn("{} {}: {} {}{}", std::string(h.method_string()), route.match.route->pattern, forbidden ? 403 : 401,
                 d.reason, LogLimit::left_out_note(left_out, "refusals"));
  return res;
}

HttpResponse Api::unrouted(const Route& route, const http::request_header<>& h) {
  const protocol::RouteSpec* spec = route.match.route;
  if (!spec) return json_error(http::status::not_found, "no such endpoint: " + std::string(h.target()), h.version());
  std::string allow;
  for (const protocol::MethodSpec& m : spec->methods) allow += (allow.empty() ? "" : ", ") + std::string(m.name);
  HttpResponse res = json_error(http::status::method_not_allowed,
                                std::string(h.method_string()) + " is not allowed on " + std::string(spec->pattern) +
                                    " (allowed: " + allow + ")",
                                h.version());
  res.set(http::field::allow, allow);
  return res;
}

std::optional<HttpResponse> Api::routed_early_response(const http::request_header<>& h, const Route& route) noexcept {
  try {
    // No route or no such method: answered from the header, before any body byte is read.
    if (!route.method) {
      HttpResponse res = unrouted(route, h);
      metrics_.observe_request(route.match.route ? "other " + std::string(route.match.route->pattern) : "unmatched", 0.0);
      return res;
    }
    std::optional<HttpResponse> res = check_access(route, h);
    if (!res) {
      // A request the disk has no room for is refused before its body is read.
      try {
        disk_.require(route.method->room);
      } catch (const ApiError& e) {
        res = json_error(http::status(e.status), e.what(), h.version());
      }
    }
    if (res) metrics_.observe_request(std::string(h.method_string()) + " " + std::string(route.match.route->pattern), 0.0);
    return res;
  } catch (...) {
    return json_error(http::status::internal_server_error, "internal error", h.version());
  }
}

HttpResponse Api::refusal(std::exception_ptr error, const HttpRequest& req) const {
  const unsigned version = req.version();
  try {
    std::rethrow_exception(error);
  } catch (const ProtocolError& e) {
    return json_error(http::status::bad_request, e.what(), version);
  } catch (const ApiError& e) {
    HttpResponse res = json_error(http::status(e.status), e.what(), version);
    if (e.status == 429) res.set(http::field::retry_after, std::to_string(opt_.retry_after_seconds));
    return res;
  } catch (const std::exception& e) {
    if (is_disk_full(e)) {
      disk_.note_full(e.what());
      return json_error(http::status::insufficient_storage, disk_.refusal(e.what()).what(), version);
    }
    spdlog::error("{} {}: internal error: {}", std::string(req.method_string()), std::string(req.target()), e.what());
    return json_error(http::status::internal_server_error, std::string("internal error: ") + e.what(), version);
  } catch (...) {
    spdlog::error("{} {}: internal error (unknown exception)", std::string(req.method_string()), std::string(req.target()));
    return json_error(http::status::internal_server_error, "internal error", version);
  }
}

void Api::answer(HttpRequest&& req, const Route& route, std::function<void(HttpReply)> send) noexcept {
  const auto t0 = std::chrono::steady_clock::now();
  const unsigned version = req.version();
  // What every answer gets on its way out, now or later: a HEAD answer loses its body, the route's latency is counted.
  struct Finish {
    Api* api;
    std::chrono::steady_clock::time_point t0;
    std::string label = "unmatched";
    bool head = false;
    std::function<void(HttpReply)> send;
    void operator()(HttpReply reply) const noexcept {
      HttpResponse& res = reply.response;
      try {
        if (head && !res.body().empty()) {
          const size_t n = res.body().size();
          res.body().clear();
          res.content_length(n);
        }
        if (head && reply.stream) {
          reply.stream->stop();  // the header alone, with the Content-Length the body would have had
          reply.stream.reset();
        }
        // A lease request held for work is counted apart, so that the route's times stay its service times.
        const bool held = res.find(protocol::kHeldMsHeader) != res.end();
        api->metrics_.observe_request(held ? label + " (held)" : label,
                                      std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count());
      } catch (...) {
        const unsigned v = res.version();
        reply = HttpReply{HttpResponse{http::status::internal_server_error, v}};
        reply.response.content_length(0);
      }
      send(std::move(reply));
    }
  };
  auto finish = std::make_shared<Finish>(Finish{this, t0, "unmatched", req.method() == http::verb::head, std::move(send)});
  try {
    const protocol::RouteSpec* spec = route.match.route;
    if (!spec || !route.method) {
      if (spec) finish->label = "other " + std::string(spec->pattern);
      return (*finish)(unrouted(route, req.base()));
    }
    const std::string pattern(spec->pattern);
    finish->label = std::string(req.method_string()) + " " + pattern;
    if (auto denied = check_access(route, req.base())) return (*finish)(std::move(*denied));
    if (spec->resource == protocol::Resource::events) return (*finish)(events_handler_.open(req).response);  // the header only
    // The request's method and target, for a refusal's log line, once the handler has let go of the request.
    ResourceHandler& handler = handler_for(spec->resource);
    if (std::optional<HttpReply> streamed = handler.stream(route.match, req)) return (*finish)(std::move(*streamed));
    auto head = std::make_shared<HttpRequest>(req.method(), std::string(req.target()), version);
    handler.handle_async(route.match, req, [this, finish, head](HttpResponse res, std::exception_ptr e) {
      (*finish)(e ? refusal(e, *head) : std::move(res));
    });
  } catch (...) {
    (*finish)(refusal(std::current_exception(), req));
  }
}

void Api::handle_routed(HttpRequest&& req, const Route& route, Reply done) noexcept {
  try {
    if (route.match.endpoint() == RouteId::events && route.method && !check_access(route, req.base())) {
      metrics_.observe_request("GET " + std::string(route.match.route->pattern), 0.0);
      return done(events_handler_.open(req));
    }
  } catch (...) {
    return done({refusal(std::current_exception(), req), nullptr});  // a bad ?only= is a 400
  }
  answer(std::move(req), route, std::move(done));
}

ResourceHandler& Api::handler_for(protocol::Resource resource) {
  switch (resource) {
    case protocol::Resource::health: return health_handler_;
    case protocol::Resource::blobs: return blobs_handler_;
    case protocol::Resource::jobs: return jobs_handler_;
    case protocol::Resource::tiles: return tiles_handler_;
    case protocol::Resource::workers: return workers_handler_;
    case protocol::Resource::leases: return leases_handler_;
    case protocol::Resource::webhooks: return webhooks_handler_;
    case protocol::Resource::steps: return outputs_handler_;
    case protocol::Resource::events: break;  // answered by the router itself (a stream)
  }
  throw ApiError(404, "no such endpoint");
}

}  // namespace tessera::server
