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
  return Access::admin;  // no such route: the strictest answer
}

Api::Api(Scheduler& scheduler, BlobStore& blobs, CoordinatorStore& jobs, Metrics& metrics, ClockMs clock,
         ApiOptions options, EventBus& bus, FarmEvents& events, DiskSpace& disk, Background background,
         Background results)
    : metrics_(metrics),
      disk_(disk),
      opt_(options),
      credentials_(opt_.tokens),
      sched_(scheduler),
      lease_waiters_(std::make_unique<LeaseWaiters>()),
      steps_(scheduler, jobs, opt_.steps),
      jobs_(scheduler, blobs, jobs, metrics, clock,
            static_cast<const AdmissionLimits&>(opt_),
            events, disk, std::move(results)),
      collector_(jobs_, scheduler, blobs, clock, opt_.retention),
      audit_(jobs, clock, opt_.retention.retain_finished_ms),
      jobs_handler_(jobs_, collector_),
      tiles_handler_(jobs_),
      leases_handler_(scheduler, jobs_, metrics, clock, events, *lease_waiters_, std::move(background)),
      workers_handler_(scheduler, opt_.heartbeat_seconds, opt_.registrations_per_minute, clock, events),
      blobs_handler_(blobs),
      health_handler_(scheduler, metrics, clock, *lease_waiters_, disk, jobs),
      events_handler_(bus),
      users_handler_(audit_),
      webhooks_handler_(opt_.webhook_log),
      outputs_handler_(steps_) {
  jobs_.use_steps(&steps_);
  sched_.on_work([w = lease_waiters_.get()] { w->note_work(); });
  share_farm();
}

void Api::share_farm() {
  std::map<std::string, OwnerShare, std::less<>> shares;
  for (const User& u : credentials_.users()) shares[u.name] = OwnerShare{u.weight, u.max_workers};
  sched_.set_shares(std::move(shares));
}

size_t Api::reload_users() {
  const size_t n = credentials_.reload();
  share_farm();
  const size_t ended = events_handler_.end_unless(
      [this](const std::string& credential) { return credentials_.admits(credential, Access::read); });
  if (ended) spdlog::info("users file: ended {} event stream(s) whose credential it no longer admits", ended);
  return n;
}

SweepReport Api::sweep() {
  SweepReport r = collector_.sweep();
  audit_.sweep();
  return r;
}

Api::~Api() {
  sched_.on_work({});
  lease_waiters_.reset();  // expires what it holds, answering through the handlers and the transport, which still live
}

bool Api::authenticated(const http::request_header<>& h) noexcept {
  try {
    return credentials_.authorize(Access::either, h[http::field::authorization], h[kClientCertNameField]).status ==
           AuthDecision::allowed;
  } catch (...) {
    return false;
  }
}

std::size_t Api::routed_body_limit(const http::request_header<>&, const Route& route) {
  if (route.method && route.match.endpoint() == RouteId::blob && route.method->name == "PUT") return opt_.blob_limit;
  if (route.method && route.match.endpoint() == RouteId::lease_result) return opt_.result_limit;  // PUT only
  return opt_.json_limit;
}

std::optional<HttpResponse> Api::check_access(const Route& route, const http::request_header<>& h, Caller* caller,
                                              std::string* credential) {
  const AuthDecision d =
      credentials_.authorize(route.method->access, h[http::field::authorization], h[kClientCertNameField]);
  if (d.status == AuthDecision::allowed) {
    if (caller) *caller = d.caller;
    if (credential) *credential = d.credential;
    return std::nullopt;
  }
  const bool forbidden = d.status == AuthDecision::wrong_role;
  if (forbidden && AuditTrail::records(*route.match.route, *route.method))
    audit_.record(d.caller, *route.match.route, *route.method, route.match.param, std::string(h[kPeerAddressField]), 403);
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

std::optional<HttpResponse> Api::check_owner(const Route& route, const HttpRequest& req, const Caller& caller) {
  if (route.method->access != Access::owner || protocol::acts_on_any_job(caller.role)) return std::nullopt;
  const std::optional<std::string> owner = sched_.job_owner(route.match.param);
  if (!owner || *owner == caller.user) return std::nullopt;  // an unknown job is its handler's 404
  return json_error(http::status::forbidden,
                    "job " + route.match.param + " belongs to " + (owner->empty() ? "no recorded user" : *owner) +
                        "; only its owner or an admin may " + std::string(req.method_string()) + " " +
                        std::string(route.match.route->pattern),
                    req.version());
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
    std::optional<Caller> audited{};                // the caller of a request the audit trail records
    const protocol::RouteSpec* spec = nullptr;      // (with audited) its route, from the static table
    const protocol::MethodSpec* method = nullptr;   // (with audited) its method
    std::string target{};                           // (with audited) the job or worker it names
    std::string address{};                          // (with audited) the peer's address
    void operator()(HttpReply reply) const noexcept {
      HttpResponse& res = reply.response;
      try {
        if (audited) {
          // A submission's target is the job it made (its Location), a control's the job or worker it named.
          std::string made = target;
          if (const auto loc = res.find(http::field::location); loc != res.end())
            made = std::string(loc->value().substr(loc->value().rfind('/') + 1));
          api->audit_.record(*audited, *spec, *method, made, address, int(res.result_int()));
        }
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
    Caller caller;
    std::string credential;
    if (auto denied = check_access(route, req.base(), &caller, &credential)) return (*finish)(std::move(*denied));
    if (AuditTrail::records(*spec, *route.method)) {
      finish->audited = caller;
      finish->spec = spec;
      finish->method = route.method;
      finish->target = route.match.param;
      finish->address = std::string(req[kPeerAddressField]);
    }
    if (auto denied = check_owner(route, req, caller)) return (*finish)(std::move(*denied));
    if (spec->resource == protocol::Resource::events)
      return (*finish)(events_handler_.open(req, credential).response);  // the header only
    // The request's method and target, for a refusal's log line, once the handler has let go of the request.
    ResourceHandler& handler = handler_for(spec->resource);
    if (std::optional<HttpReply> streamed = handler.stream(route.match, req, caller)) return (*finish)(std::move(*streamed));
    auto head = std::make_shared<HttpRequest>(req.method(), std::string(req.target()), version);
    handler.handle_async(route.match, req, caller, [this, finish, head](HttpResponse res, std::exception_ptr e) {
      (*finish)(e ? refusal(e, *head) : std::move(res));
    });
  } catch (...) {
    (*finish)(refusal(std::current_exception(), req));
  }
}

void Api::handle_routed(HttpRequest&& req, const Route& route, Reply done) noexcept {
  try {
    std::string credential;
    if (route.match.endpoint() == RouteId::events && route.method && !check_access(route, req.base(), nullptr, &credential)) {
      metrics_.observe_request("GET " + std::string(route.match.route->pattern), 0.0);
      return done(events_handler_.open(req, credential));
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
    case protocol::Resource::users: return users_handler_;
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
