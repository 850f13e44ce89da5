// The farm protocol's endpoints (docs/protocol.md): routing, request validation and responses over the scheduler,
// the stores and the job images. Knows HTTP messages, not sockets.
#pragma once

#include "protocol/messages.h"
#include "protocol/routes.h"
#include "server/assembly.h"
#include "server/auth.h"
#include "server/http_server.h"
#include "server/metrics.h"
#include "server/scheduler.h"
#include "server/storage.h"

#include <nlohmann/json.hpp>

#include <cstddef>
#include <cstdint>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

namespace tessera::server {

/// Size limits and timings the API announces and enforces.
struct ApiOptions {
  std::size_t json_limit = std::size_t(16) << 20;    ///< JSON request bodies.
  std::size_t blob_limit = std::size_t(256) << 20;   ///< Blob uploads.
  std::size_t result_limit = std::size_t(64) << 20;  ///< Tile result uploads.
  int heartbeat_seconds = protocol::kDefaultHeartbeatSeconds;  ///< Heartbeat interval announced to workers.
  AccessTokens tokens;                               ///< Bearer tokens (empty: that side's endpoints are open).
  int64_t max_queued_jobs = 1000;                    ///< Queued plus running jobs; more submissions get 429.
  int retry_after_seconds = 30;                      ///< Retry-After announced with 429.
  uint64_t max_job_pixels = uint64_t(1) << 26;       ///< width x height of one job (the merged image lives in memory).
  double max_job_samples = 4e10;                     ///< width x height x spp (x max_spp when adaptive) of one job.
};

/// The endpoints a request target can name (protocol/routes.h).
using RouteId = protocol::Endpoint;

/// A matched request target.
struct Route {
  RouteId id = RouteId::none;          ///< Which endpoint (none: 404).
  std::string param;                   ///< The id or hash in the path.
  std::string name;                    ///< Route label for logs and metrics, e.g. "GET /v1/jobs/{id}".
  std::vector<http::verb> methods;     ///< Methods the endpoint accepts.
};

/// Matches a request target (query string ignored) to an endpoint.
Route match_route(std::string_view target);

/// The token an endpoint needs for a method (see docs/protocol.md, "Access").
Access route_access(RouteId route, http::verb method);

/// The HTTP handler implementing docs/protocol.md.
class Api final : public HttpHandler {
 public:
  /// An API over the given state; all references must outlive it.
  Api(Scheduler& scheduler, BlobStore& blobs, JobStore& jobs, Metrics& metrics, ClockMs clock, ApiOptions options);
  std::size_t body_limit(const http::request_header<>& header) override;
  std::optional<HttpResponse> early_response(const http::request_header<>& header) noexcept override;
  HttpResponse handle(HttpRequest&& request) noexcept override;
  /// After a restart: finishes jobs whose every tile was stored but whose result was not written yet.
  void recover();

 private:
  std::optional<HttpResponse> check_access(const Route& route, const http::request_header<>& header);
  HttpResponse dispatch(const Route& route, HttpRequest& req);
  HttpResponse put_blob(const std::string& sha, HttpRequest& req);
  HttpResponse head_blob(const std::string& sha, HttpRequest& req);
  HttpResponse get_blob(const std::string& sha, HttpRequest& req);
  HttpResponse post_job(HttpRequest& req);
  HttpResponse list_jobs(HttpRequest& req);
  HttpResponse get_job(const std::string& id, HttpRequest& req);
  HttpResponse delete_job(const std::string& id, HttpRequest& req);
  HttpResponse get_result(const std::string& id, HttpRequest& req);
  HttpResponse get_preview(const std::string& id, HttpRequest& req);
  HttpResponse get_spec(const std::string& id, HttpRequest& req);
  HttpResponse post_worker(HttpRequest& req);
  HttpResponse post_lease(const std::string& worker, HttpRequest& req);
  HttpResponse post_heartbeat(const std::string& lease, HttpRequest& req);
  HttpResponse put_result(const std::string& lease, HttpRequest& req);
  HttpResponse post_fail(const std::string& lease, HttpRequest& req);
  HttpResponse post_release(const std::string& lease, HttpRequest& req);

  std::shared_ptr<JobImage> image_for(const std::string& job, int width, int height);
  void drop_image(const std::string& job);
  void finalize(const std::string& job);

  Scheduler& sched_;
  BlobStore& blobs_;
  JobStore& jobs_;
  Metrics& metrics_;
  ClockMs clock_;
  ApiOptions opt_;
  std::mutex mu_;
  std::mutex admit_mu_;                                      // makes the queued-jobs check and add_job one step
  std::map<std::string, std::shared_ptr<JobImage>> images_;  // running jobs' images (a cache of the stored tiles)
  std::map<std::string, protocol::JobSpec> specs_;           // job id -> what workers need to build the scene
};

}  // namespace tessera::server
