#include "server/admission_handler.h"

#include "protocol/routes.h"

#include <boost/asio/post.hpp>
#include <spdlog/spdlog.h>

#include <memory>
#include <stdexcept>
#include <string>

namespace tessera::server {

namespace {

bool is_submission(const HttpRequest& req) {
  if (req.method() != http::verb::post) return false;
  const protocol::RouteMatch m = protocol::match_route(req.target());
  return m.route && m.route->endpoint == protocol::Endpoint::jobs;
}

}  // namespace

AdmissionHandler::AdmissionHandler(HttpHandler& inner, AdmissionOptions options)
    : inner_(inner), opt_(options), pool_(std::size_t(options.validations)) {
  if (options.validations < 1) throw std::invalid_argument("at least one submission must be checked at a time");
  if (options.queue < 0) throw std::invalid_argument("the submission queue cannot be negative");
}

AdmissionHandler::~AdmissionHandler() {
  pool_.stop();
  pool_.join();
}

void AdmissionHandler::handle_async(HttpRequest&& req, Reply done) noexcept {
  const unsigned version = req.version();
  bool counted = false;
  try {
    if (!is_submission(req)) return inner_.handle_async(std::move(req), std::move(done));
    const int limit = opt_.validations + opt_.queue;
    const int ahead = in_flight_.fetch_add(1);
    if (ahead >= limit) {
      in_flight_.fetch_sub(1);
      spdlog::warn("POST /v1/jobs: 503, {} submission(s) are being checked or waiting (--max-validations {}, "
                   "--validation-queue {})", limit, opt_.validations, opt_.queue);
      HttpResponse res = json_error(http::status::service_unavailable,
                                    "busy: " + std::to_string(limit) + " submissions are being checked or waiting "
                                    "(--max-validations, --validation-queue); retry later", version);
      res.set(http::field::retry_after, std::to_string(opt_.retry_after_seconds));
      return done({std::move(res), nullptr});
    }
    counted = true;
    if (ahead >= opt_.validations) spdlog::info("POST /v1/jobs: waiting for a scene check ({} submission(s) ahead)", ahead);
    auto owned = std::make_shared<HttpRequest>(std::move(req));
    boost::asio::post(pool_, [this, owned, done]() {
      HttpResponse res = inner_.handle(std::move(*owned));
      in_flight_.fetch_sub(1);
      done({std::move(res), nullptr});
    });
  } catch (const std::exception& e) {
    if (counted) in_flight_.fetch_sub(1);
    done({json_error(http::status::internal_server_error, std::string("internal error: ") + e.what(), version), nullptr});
  }
}

}  // namespace tessera::server
