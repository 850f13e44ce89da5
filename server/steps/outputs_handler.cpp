#include "server/steps/outputs_handler.h"

#include "server/file_stream.h"

namespace tessera::server {

HttpResponse OutputsHandler::handle(const protocol::RouteMatch&, HttpRequest&, const Caller&) {
  throw protocol::ApiError(404, "no such endpoint");  // every answer is a stream
}

std::optional<HttpReply> OutputsHandler::stream(const protocol::RouteMatch& route, HttpRequest& req, const Caller& /*caller*/) {
  const std::filesystem::path file = runner_.output_file(route.param, route.param2);
  const std::string ext = file.extension().string();
  const char* type = ext == ".png"   ? "image/png"
                     : ext == ".exr" ? "image/x-exr"
                     : ext == ".mp4" ? "video/mp4"
                                     : "application/octet-stream";
  std::optional<HttpReply> r = file_reply(file, type, req.version());
  if (!r) throw protocol::ApiError(404, "job " + route.param + " has no output " + route.param2);
  return r;
}

}  // namespace tessera::server
