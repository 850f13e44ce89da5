// Client endpoints of jobs: submit, list, show, cancel, result, preview, and the spec workers build from.
#pragma once

#include "server/job_service.h"
#include "server/resource_handler.h"

namespace tessera::server {

/// /v1/jobs, /v1/jobs/{id}, /v1/jobs/{id}/result.exr, /preview.png, /spec, /retry, /pause and /resume.
class JobsHandler final : public ResourceHandler {
 public:
  /// Endpoints over `jobs` (which must outlive it).
  explicit JobsHandler(JobService& jobs) : jobs_(jobs) {}
  HttpResponse handle(protocol::Endpoint endpoint, const std::string& id, HttpRequest& req) override;

 private:
  JobService& jobs_;
};

}  // namespace tessera::server
