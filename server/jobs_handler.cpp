#include "server/jobs_handler.h"

#include "server/file_stream.h"

#include <optional>

namespace tessera::server {

using protocol::Endpoint;

HttpResponse JobsHandler::handle(const protocol::RouteMatch& route, HttpRequest& req, const Caller& caller) {
  const Endpoint endpoint = route.endpoint();
  const std::string& id = route.param;
  const unsigned v = req.version();
  const bool get = req.method() == http::verb::get;
  switch (endpoint) {
    case Endpoint::jobs: {
      if (get) return json_response(http::status::ok, jobs_.list(protocol::parse_job_list_query(req.target())), v);
      const protocol::SubmitAnswer a = jobs_.submit(protocol::parse_job_submission(req.body()), caller.user);
      HttpResponse res = json_response(http::status::created, a, v);
      res.set(http::field::location, protocol::routes::job(a.id));
      return res;
    }
    case Endpoint::job:
      if (get) return json_response(http::status::ok, jobs_.status(id), v);
      if (req.method() == http::verb::patch) {
        const protocol::JobPatch patch = protocol::parse_job_patch(req.body());
        std::optional<protocol::JobStatus> raised;
        if (patch.spp) raised = jobs_.raise_spp(id, *patch.spp);
        return json_response(http::status::ok, patch.priority ? jobs_.set_priority(id, *patch.priority) : *raised, v);
      }
      // DELETE without purge=true cancels (as it always has); with it, deletes a job that has ended.
      if (!protocol::parse_purge_query(req.target())) return json_response(http::status::ok, jobs_.cancel(id), v);
      return json_response(http::status::ok, protocol::PurgeAnswer{id, collector_.purge(id)}, v);
    case Endpoint::job_preview: {
      const std::vector<uint8_t> png = jobs_.preview_png(id, protocol::parse_preview_query(req.target()));
      return bytes_response(std::string(png.begin(), png.end()), "image/png", v);
    }
    case Endpoint::job_spec: return bytes_response(jobs_.spec_json(id), "application/json", v);
    case Endpoint::job_retry:
      return json_response(http::status::ok, jobs_.retry(id, protocol::parse_retry_request(req.body()).frames), v);
    case Endpoint::job_frames:
      return json_response(http::status::ok, jobs_.frames(id, protocol::parse_frame_list_query(req.target())), v);
    case Endpoint::job_pause:
      protocol::parse_empty_request(req.body());
      return json_response(http::status::ok, jobs_.pause(id), v);
    case Endpoint::job_resume:
      protocol::parse_empty_request(req.body());
      return json_response(http::status::ok, jobs_.resume(id), v);
    default: break;
  }
  throw protocol::ApiError(404, "no such endpoint");
}

std::optional<HttpReply> JobsHandler::stream(const protocol::RouteMatch& route, HttpRequest& req, const Caller& /*caller*/) {
  if (route.endpoint() != Endpoint::job_result && route.endpoint() != Endpoint::job_frame_result) return std::nullopt;
  // A frame's result is its own job's.
  const std::string job =
      route.endpoint() == Endpoint::job_result ? route.param : jobs_.frame_job(route.param, route.param2);
  std::optional<HttpReply> r = file_reply(jobs_.result_exr(job), "image/x-exr", req.version());
  if (!r) throw protocol::ApiError(404, "job " + job + " has no stored result");
  return r;
}

}  // namespace tessera::server
