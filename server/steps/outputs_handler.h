// GET /v1/jobs/{id}/outputs/{name}: a file written by a done job's steps (server/steps/step_runner.h), streamed.
#pragma once

#include "server/resource_handler.h"
#include "server/steps/step_runner.h"

namespace tessera::server {

/// The steps resource.
class OutputsHandler final : public ResourceHandler {
 public:
  /// Serves the files of `runner` (which must outlive it).
  explicit OutputsHandler(StepRunner& runner) : runner_(runner) {}
  HttpResponse handle(const protocol::RouteMatch& route, HttpRequest& req, const Caller& caller) override;
  std::optional<HttpReply> stream(const protocol::RouteMatch& route, HttpRequest& req, const Caller& caller) override;

 private:
  StepRunner& runner_;
};

}  // namespace tessera::server
