// Client endpoints of jobs: submit, list, show, cancel, result, preview, and the spec workers build from.
#pragma once

#include "server/collector.h"
#include "server/job_service.h"
#include "server/resource_handler.h"

namespace tessera::server {

/// /v1/jobs, /v1/jobs/{id}, /v1/jobs/{id}/result.exr, /preview.png, /spec, /retry, /pause and /resume.
class JobsHandler final : public ResourceHandler {
 public:
  /// Endpoints over `jobs`, purging through `collector` (both must outlive it).
  JobsHandler(JobService& jobs, Collector& collector) : jobs_(jobs), collector_(collector) {}
  HttpResponse handle(const protocol::RouteMatch& route, HttpRequest& req, const Caller& caller) override;
  /// The result EXR, streamed from its file.
  std::optional<HttpReply> stream(const protocol::RouteMatch& route, HttpRequest& req, const Caller& caller) override;

 private:
  JobService& jobs_;
  Collector& collector_;
};

}  // namespace tessera::server
