#include "server/workers_handler.h"

#include <spdlog/spdlog.h>

namespace tessera::server {

using protocol::Endpoint;

namespace {
// When a registration refused for want of room may be tried again.
constexpr int kFullRetryAfterSeconds = 60;
}  // namespace

HttpResponse WorkersHandler::handle(const protocol::RouteMatch& route, HttpRequest& req, const Caller& /*caller*/) {
  const Endpoint endpoint = route.endpoint();
  const std::string& id = route.param;
  const unsigned v = req.version();
  if (endpoint == Endpoint::worker_drain || endpoint == Endpoint::worker_undrain) {
    protocol::parse_empty_request(req.body());
    const bool drain = endpoint == Endpoint::worker_drain;
    const std::optional<protocol::WorkerInfo> w = sched_.set_drained(id, drain);
    if (!w) throw protocol::ApiError(404, "no worker " + id);
    spdlog::info("worker {}: {}", id, drain ? "draining (no new tiles)" : "undrained");
    events_.worker_drained(*w, drain);
    return json_response(http::status::ok, *w, v);
  }
  if (req.method() == http::verb::get) return json_response(http::status::ok, protocol::WorkerList{sched_.workers()}, v);
  return register_worker(req);
}

HttpResponse WorkersHandler::register_worker(HttpRequest& req) {
  const unsigned v = req.version();
  const protocol::WorkerHello hello = protocol::parse_worker_hello(req.body());
  if (const int64_t wait_ms = registrations_.take(clock_()); wait_ms > 0) {
    HttpResponse res = json_error(http::status::too_many_requests,
                                  "too many worker registrations: the coordinator takes " +
                                      fmt::format("{:g}", registrations_per_minute_) +
                                      " a minute (--max-registrations-per-minute); try again later",
                                  v);
    res.set(http::field::retry_after, std::to_string((wait_ms + 999) / 1000));
    return res;
  }
  const RegisterResult r = sched_.register_worker(hello.name, hello.threads, hello.tags);
  if (r.status == RegisterResult::full) {
    HttpResponse res = json_error(http::status::service_unavailable,
                                  "the coordinator has " + std::to_string(sched_.config().max_workers) +
                                      " registered workers, its --max-workers; a worker offline for its "
                                      "--worker-retention-seconds is forgotten and frees its place",
                                  v);
    res.set(http::field::retry_after, std::to_string(kFullRetryAfterSeconds));
    return res;
  }
  spdlog::info("worker {}: registered '{}' ({} threads, version {})", r.id, hello.name, hello.threads,
               hello.version.empty() ? "?" : hello.version);
  if (const std::optional<protocol::WorkerInfo> w = sched_.worker(r.id)) events_.worker_registered(*w);
  const protocol::Registration reg{r.id, double(sched_.config().lease_ms) / 1000.0, double(heartbeat_seconds_), r.secret};
  HttpResponse res = json_response(http::status::created, reg, v);
  res.set(http::field::location, protocol::routes::workers() + "/" + r.id);
  return res;
}

}  // namespace tessera::server
