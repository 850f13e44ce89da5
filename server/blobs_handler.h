// Content-addressed assets: upload, check (one or many), download.
#pragma once

#include "server/resource_handler.h"
#include "server/storage.h"

namespace tessera::server {

/// POST /v1/blobs (which of these are missing?) and PUT, HEAD and GET /v1/blobs/{sha256}.
class BlobsHandler final : public ResourceHandler {
 public:
  /// Endpoints over `blobs` (which must outlive it).
  explicit BlobsHandler(BlobStore& blobs) : blobs_(blobs) {}
  HttpResponse handle(const protocol::RouteMatch& route, HttpRequest& req, const Caller& caller) override;
  /// GET of a blob, streamed from its file.
  std::optional<HttpReply> stream(const protocol::RouteMatch& route, HttpRequest& req, const Caller& caller) override;

 private:
  BlobStore& blobs_;
};

}  // namespace tessera::server
