#include "server/workers_handler.h"

#include <spdlog/spdlog.h>

namespace tessera::server {

HttpResponse WorkersHandler::handle(protocol::Endpoint, const std::string&, HttpRequest& req) {
  const protocol::WorkerHello hello = protocol::parse_worker_hello(req.body());
  const std::string id = sched_.register_worker(hello.name);
  spdlog::info("worker {}: registered '{}' ({} threads, version {})", id, hello.name, hello.threads,
               hello.version.empty() ? "?" : hello.version);
  const protocol::Registration reg{id, double(sched_.config().lease_ms) / 1000.0, double(heartbeat_seconds_)};
  HttpResponse res = json_response(http::status::created, reg, req.version());
  res.set(http::field::location, protocol::routes::workers() + "/" + id);
  return res;
}

}  // namespace tessera::server
