#include "server/workers_handler.h"

#include <spdlog/spdlog.h>

namespace tessera::server {

using protocol::Endpoint;

HttpResponse WorkersHandler::handle(const protocol::RouteMatch& route, HttpRequest& req) {
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
  const protocol::WorkerHello hello = protocol::parse_worker_hello(req.body());
  const std::string id_new = sched_.register_worker(hello.name, hello.threads);
  spdlog::info("worker {}: registered '{}' ({} threads, version {})", id_new, hello.name, hello.threads,
               hello.version.empty() ? "?" : hello.version);
  for (const protocol::WorkerInfo& w : sched_.workers())
    if (w.id == id_new) events_.worker_registered(w);
  const protocol::Registration reg{id_new, double(sched_.config().lease_ms) / 1000.0, double(heartbeat_seconds_)};
  HttpResponse res = json_response(http::status::created, reg, v);
  res.set(http::field::location, protocol::routes::workers() + "/" + id_new);
  return res;
}

}  // namespace tessera::server
