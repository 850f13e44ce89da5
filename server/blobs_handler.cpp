#include "server/blobs_handler.h"

#include "core/util/sha256.h"
#include "server/file_stream.h"

#include <spdlog/spdlog.h>

#include <filesystem>

namespace fs = std::filesystem;

namespace tessera::server {

using protocol::ApiError;

HttpResponse BlobsHandler::handle(const protocol::RouteMatch& route, HttpRequest& req, const Caller& /*caller*/) {
  const protocol::Endpoint endpoint = route.endpoint();
  const std::string& sha = route.param;
  if (endpoint == protocol::Endpoint::blobs) {
    // A client checks every blob of a submission at once: each one held starts its grace period again (as HEAD).
    const protocol::BlobQuery q = protocol::parse_blob_query(req.body());
    protocol::BlobQueryAnswer answer;
    for (const std::string& h : q.sha256)
      if (!blobs_.touch(h)) answer.missing.push_back(h);
    return json_response(http::status::ok, answer, req.version());
  }
  if (req.method() == http::verb::put) {
    if (!is_sha256_hex(sha))
      throw ApiError(400, "blob path must be 64 lowercase hex digits (a SHA-256), got '" + sha + "'");
    const PutBlobResult r = blobs_.put(sha, req.body());
    if (r.status == PutBlobResult::mismatch) throw ApiError(400, "body hashes to " + r.actual + ", not " + sha);
    if (r.status == PutBlobResult::created) spdlog::info("blob {}: stored ({} bytes)", sha, r.size);
    return json_response(r.status == PutBlobResult::created ? http::status::created : http::status::ok,
                         protocol::BlobPutAnswer{sha, r.size}, req.version());
  }
  if (req.method() == http::verb::head) {
    // A client checks the blobs of a submission it is about to send: the blob's grace period starts again.
    blobs_.touch(sha);
    const std::optional<fs::path> f = blobs_.file(sha);
    HttpResponse res{f ? http::status::ok : http::status::not_found, req.version()};
    std::error_code ec;
    res.content_length(f ? uint64_t(fs::file_size(*f, ec)) : 0);
    if (f) res.set(http::field::content_type, "application/octet-stream");
    return res;
  }
  throw ApiError(404, "blob " + sha + " is not stored");  // GET is answered by stream()
}

std::optional<HttpReply> BlobsHandler::stream(const protocol::RouteMatch& route, HttpRequest& req, const Caller& /*caller*/) {
  if (route.endpoint() != protocol::Endpoint::blob || req.method() != http::verb::get) return std::nullopt;
  const std::optional<fs::path> f = blobs_.file(route.param);
  std::optional<HttpReply> r = f ? file_reply(*f, "application/octet-stream", req.version()) : std::nullopt;
  if (!r) throw ApiError(404, "blob " + route.param + " is not stored");
  return r;
}

}  // namespace tessera::server
