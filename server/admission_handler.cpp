#include "server/admission_handler.h"

#include <boost/asio/post.hpp>
#include <spdlog/spdlog.h>

#include <memory>
#include <stdexcept>
#include <string>

namespace tessera::server {

AdmissionHandler::AdmissionHandler(RoutedHandler& inner, AdmissionOptions options)
    : inner_(inner), opt_(options), pool_(std::size_t(options.validations)) {
  if (options.validations < 1) throw std::invalid_argument("at least one submission must be checked at a time");
  if (options.queue < 0) throw std::invalid_argument("the submission queue cannot be negative");
}

AdmissionHandler::~AdmissionHandler() {
  pool_.stop();
  pool_.join();
}

void AdmissionHandler::handle_routed(HttpRequest&& req, const Route& route, Reply done) noexcept {
  const unsigned version = req.version();
  bool counted = false;
  try {
    if (!route.admission()) return inner_.handle_routed(std::move(req), route, std::move(done));
    const int limit = opt_.validations + opt_.queue;
    const int ahead = in_flight_.fetch_add(1);
    if (ahead >= limit) {
      in_flight_.fetch_sub(1);
      spdlog::warn("{} {}: 503, {} submission(s) are being checked or waiting (--max-validations {}, "
                   "--validation-queue {})", route.method->name, route.match.route->pattern, limit, opt_.validations, opt_.queue);
      HttpResponse res = json_error(http::status::service_unavailable,
                                    "busy: " + std::to_string(limit) + " submissions are being checked or waiting "
                                    "(--max-validations, --validation-queue); retry later", version);
      res.set(http::field::retry_after, std::to_string(opt_.retry_after_seconds));
      return done({std::move(res), nullptr});
    }
    counted = true;
    if (ahead >= opt_.validations) spdlog::info("{} {}: waiting for a scene check ({} submission(s) ahead)", route.method->name,
                                                 route.match.route->pattern, ahead);
    auto owned = std::make_shared<HttpRequest>(std::move(req));
    boost::asio::post(pool_, [this, owned, route, done]() {
      inner_.handle_routed(std::move(*owned), route, [this, done](HttpReply r) {
        in_flight_.fetch_sub(1);
        done({std::move(r.response), nullptr});
      });
    });
  } catch (const std::exception& e) {
    if (counted) in_flight_.fetch_sub(1);
    done({json_error(http::status::internal_server_error, std::string("internal error: ") + e.what(), version), nullptr});
  }
}

}  // namespace tessera::server
