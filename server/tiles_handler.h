// Client endpoints of one job's tiles: the tile table and requeueing a tile.
#pragma once

#include "server/job_service.h"
#include "server/resource_handler.h"

namespace tessera::server {

/// /v1/jobs/{id}/tiles and /v1/jobs/{id}/tiles/{n}/requeue.
class TilesHandler final : public ResourceHandler {
 public:
  /// Endpoints over `jobs` (which must outlive it).
  explicit TilesHandler(JobService& jobs) : jobs_(jobs) {}
  HttpResponse handle(const protocol::RouteMatch& route, HttpRequest& req, const Caller& caller) override;

 private:
  JobService& jobs_;
};

}  // namespace tessera::server
