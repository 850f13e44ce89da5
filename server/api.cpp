#include "server/api.h"

#include <spdlog/spdlog.h>

#include <algorithm>
#include <chrono>
#include <future>
#include <memory>

namespace tessera::server {

using protocol::ApiError;
using protocol::ProtocolError;

Route match_route(std::string_view target) {
  const protocol::RouteMatch m = protocol::match_route(target);
  Route r;
  if (!m.route) return r;
  r.id = m.route->endpoint;
  r.param = m.param;
  r.name = std::string(m.route->pattern);
  for (std::string_view v : m.route->methods) r.methods.push_back(http::string_to_verb(v));
  return r;
}

Access route_access(RouteId route, http::verb method) {
  switch (route) {
    case RouteId::healthz: return Access::open;
    case RouteId::metrics: return Access::either;
    case RouteId::blobs: return Access::client;  // which blobs a submission still has to upload
    case RouteId::blob: return method == http::verb::get ? Access::either : Access::client;  // HEAD/PUT: submitting
    case RouteId::job_spec: return Access::either;
    case RouteId::jobs:
    case RouteId::job:
    case RouteId::job_result:
    case RouteId::job_preview:
    case RouteId::job_retry:
    case RouteId::job_pause:
    case RouteId::job_resume:
    case RouteId::job_tiles:
    case RouteId::job_tile_requeue:
    case RouteId::worker_drain:
    case RouteId::worker_undrain:
    case RouteId::events: return Access::client;
    case RouteId::workers: return method == http::verb::get ? Access::client : Access::worker;  // POST: registration
    case RouteId::worker_lease:
    case RouteId::lease_heartbeat:
    case RouteId::lease_result:
    case RouteId::lease_fail:
    case RouteId::lease_release:
    case RouteId::lease_state: return Access::worker;
    case RouteId::none: break;
  }
  return Access::client;  // unreachable for matched routes; the strictest answer otherwise
}

Api::Api(Scheduler& scheduler, BlobStore& blobs, JobStore& jobs, Metrics& metrics, ClockMs clock, ApiOptions options,
         EventBus& bus, FarmEvents& events, Background background)
    : metrics_(metrics),
      opt_(options),
      token_check_(opt_.tokens),
      sched_(scheduler),
      lease_waiters_(std::make_unique<LeaseWaiters>()),
      jobs_(scheduler, blobs, jobs, metrics, clock,
            AdmissionLimits{opt_.max_queued_jobs, opt_.retry_after_seconds, opt_.max_job_pixels, opt_.max_job_samples},
            events, std::move(background)),
      collector_(jobs_, scheduler, blobs, clock, opt_.retention),
      jobs_handler_(jobs_, collector_),
      tiles_handler_(jobs_),
      leases_handler_(scheduler, jobs_, metrics, clock, events, *lease_waiters_),
      workers_handler_(scheduler, opt_.heartbeat_seconds, events),
      blobs_handler_(blobs),
      health_handler_(scheduler, metrics, clock, *lease_waiters_),
      events_handler_(bus) {
  sched_.on_work([w = lease_waiters_.get()] { w->note_work(); });
}

Api::~Api() {
  sched_.on_work({});
  lease_waiters_.reset();  // expires what it holds, answering through the handlers and the transport, which still live
}

std::size_t Api::body_limit(const http::request_header<>& h) {
  const Route r = match_route(h.target());
  if (r.id == RouteId::blob && h.method() == http::verb::put) return opt_.blob_limit;
  if (r.id == RouteId::lease_result && h.method() == http::verb::put) return opt_.result_limit;
  return opt_.json_limit;
}

std::optional<HttpResponse> Api::check_access(const Route& route, const http::request_header<>& h) {
  const AuthDecision d = token_check_.authorize(route_access(route.id, h.method()), h[http::field::authorization]);
  if (d.status == AuthDecision::allowed) return std::nullopt;
  const bool forbidden = d.status == AuthDecision::wrong_role;
  HttpResponse res = json_error(forbidden ? http::status::forbidden : http::status::unauthorized, d.reason, h.version());
  if (!forbidden)
    res.set(http::field::www_authenticate,
            d.status == AuthDecision::missing ? "Bearer realm=\"tessera\"" : "Bearer realm=\"tessera\", error=\"invalid_token\"");
  // The reason names roles, never the presented or configured token.
  spdlog::warn("{} {}: {} {}", std::string(h.method_string()), route.name, forbidden ? 403 : 401, d.reason);
  return res;
}

std::optional<HttpResponse> Api::early_response(const http::request_header<>& h) noexcept {
  try {
    const Route route = match_route(h.target());
    if (route.id == RouteId::none ||
        std::find(route.methods.begin(), route.methods.end(), h.method()) == route.methods.end())
      return std::nullopt;  // handle() answers 404/405 (after the body, which is small or refused by its limit)
    std::optional<HttpResponse> res = check_access(route, h);
    if (res) metrics_.observe_request(std::string(h.method_string()) + " " + route.name, 0.0);
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
    spdlog::error("{} {}: internal error: {}", std::string(req.method_string()), std::string(req.target()), e.what());
    return json_error(http::status::internal_server_error, std::string("internal error: ") + e.what(), version);
  } catch (...) {
    spdlog::error("{} {}: internal error (unknown exception)", std::string(req.method_string()), std::string(req.target()));
    return json_error(http::status::internal_server_error, "internal error", version);
  }
}

void Api::answer(HttpRequest&& req, std::function<void(HttpResponse)> send) noexcept {
  const auto t0 = std::chrono::steady_clock::now();
  const unsigned version = req.version();
  // What every answer gets on its way out, now or later: a HEAD answer loses its body, the route's latency is counted.
  struct Finish {
    Api* api;
    std::chrono::steady_clock::time_point t0;
    std::string label = "unmatched";
    bool head = false;
    std::function<void(HttpResponse)> send;
    void operator()(HttpResponse res) const noexcept {
      try {
        if (head && !res.body().empty()) {
          const size_t n = res.body().size();
          res.body().clear();
          res.content_length(n);
        }
        // A lease request held for work is counted apart, so that the route's times stay its service times.
        const bool held = res.find(protocol::kHeldMsHeader) != res.end();
        api->metrics_.observe_request(held ? label + " (held)" : label,
                                      std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count());
      } catch (...) {
        const unsigned v = res.version();
        res = HttpResponse{http::status::internal_server_error, v};
        res.content_length(0);
      }
      send(std::move(res));
    }
  };
  auto finish = std::make_shared<Finish>(Finish{this, t0, "unmatched", req.method() == http::verb::head, std::move(send)});
  try {
    const Route route = match_route(req.target());
    if (route.id == RouteId::none) {
      return (*finish)(json_error(http::status::not_found, "no such endpoint: " + std::string(req.target()), version));
    }
    finish->label = std::string(req.method_string()) + " " + route.name;
    if (std::find(route.methods.begin(), route.methods.end(), req.method()) == route.methods.end()) {
      std::string allow;
      for (http::verb v : route.methods) allow += (allow.empty() ? "" : ", ") + std::string(http::to_string(v));
      finish->label = "other " + route.name;
      HttpResponse res = json_error(http::status::method_not_allowed,
                                    std::string(req.method_string()) + " is not allowed on " + route.name + " (allowed: " + allow + ")", version);
      res.set(http::field::allow, allow);
      return (*finish)(std::move(res));
    }
    if (auto denied = check_access(route, req.base())) return (*finish)(std::move(*denied));
    if (route.id == RouteId::events) return (*finish)(events_handler_.open(req).response);  // only the header: reply() streams
    // The request's method and target, for a refusal's log line, once the handler has let go of the request.
    auto head = std::make_shared<HttpRequest>(req.method(), std::string(req.target()), version);
    handler_for(route.id).handle_async(route.id, route.param, req, [this, finish, head](HttpResponse res, std::exception_ptr e) {
      (*finish)(e ? refusal(e, *head) : std::move(res));
    });
  } catch (...) {
    (*finish)(refusal(std::current_exception(), req));
  }
}

HttpResponse Api::handle(HttpRequest&& req) noexcept {
  std::promise<HttpResponse> promise;
  std::future<HttpResponse> answered = promise.get_future();
  answer(std::move(req), [&promise](HttpResponse res) { promise.set_value(std::move(res)); });
  return answered.get();
}

void Api::handle_async(HttpRequest&& req, Reply done) noexcept {
  try {
    const Route route = match_route(req.target());
    if (route.id == RouteId::events && req.method() == http::verb::get && !check_access(route, req.base())) {
      metrics_.observe_request("GET " + route.name, 0.0);
      return done(events_handler_.open(req));
    }
  } catch (...) {
    return done({refusal(std::current_exception(), req), nullptr});  // a bad ?only= is a 400
  }
  answer(std::move(req), [done](HttpResponse res) { done({std::move(res), nullptr}); });
}

HttpReply Api::reply(HttpRequest&& req) noexcept {
  std::promise<HttpReply> promise;
  std::future<HttpReply> answered = promise.get_future();
  handle_async(std::move(req), [&promise](HttpReply r) { promise.set_value(std::move(r)); });
  return answered.get();
}

ResourceHandler& Api::handler_for(RouteId route) {
  switch (route) {
    case RouteId::healthz:
    case RouteId::metrics: return health_handler_;
    case RouteId::blobs:
    case RouteId::blob: return blobs_handler_;
    case RouteId::jobs:
    case RouteId::job:
    case RouteId::job_result:
    case RouteId::job_preview:
    case RouteId::job_spec:
    case RouteId::job_retry:
    case RouteId::job_pause:
    case RouteId::job_resume: return jobs_handler_;
    case RouteId::job_tiles:
    case RouteId::job_tile_requeue: return tiles_handler_;
    case RouteId::workers:
    case RouteId::worker_drain:
    case RouteId::worker_undrain: return workers_handler_;
    case RouteId::worker_lease:
    case RouteId::lease_heartbeat:
    case RouteId::lease_result:
    case RouteId::lease_fail:
    case RouteId::lease_release:
    case RouteId::lease_state: return leases_handler_;
    case RouteId::events:
    case RouteId::none: break;
  }
  throw ApiError(404, "no such endpoint");
}

}  // namespace tessera::server
