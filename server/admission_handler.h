// Scene validation off the handler pool: job submissions (POST /v1/jobs parses, loads and checks the whole scene,
// seconds on a big mesh) run on a small pool of their own, so leases, heartbeats and uploads never wait behind them.
#pragma once

#include "server/route.h"

#include <boost/asio/thread_pool.hpp>

#include <atomic>
#include <cstddef>

namespace tessera::server {

/// How many submissions are checked at once and how many may wait for their turn.
struct AdmissionOptions {
  int validations = 2;       ///< Submissions checked at the same time (threads of the admission pool).
  int queue = 8;             ///< Submissions waiting for a free thread; more are answered 503.
  int retry_after_seconds = 1;  ///< Retry-After announced with that 503.
};

/// The first handler of a request, in front of `inner`: routes it (once; `inner` is given the route) and answers the
/// routes that take admission (POST /v1/jobs, protocol/routes.h) through `inner` on the admission pool (503 with
/// Retry-After when `validations + queue` submissions are already there), every other request on the calling thread.
class AdmissionHandler final : public RoutedHandler {
 public:
  AdmissionHandler(RoutedHandler& inner, AdmissionOptions options);
  /// Lets the submissions under way finish; queued ones are dropped (their connections close unanswered).
  ~AdmissionHandler() override;
  AdmissionHandler(const AdmissionHandler&) = delete;
  AdmissionHandler& operator=(const AdmissionHandler&) = delete;

  std::size_t routed_body_limit(const http::request_header<>& header, const Route& route) override {
    return inner_.routed_body_limit(header, route);
  }
  std::optional<HttpResponse> routed_early_response(const http::request_header<>& header, const Route& route) noexcept override {
    return inner_.routed_early_response(header, route);
  }
  void handle_routed(HttpRequest&& request, const Route& route, Reply done) noexcept override;
  bool authenticated(const http::request_header<>& header) noexcept override { return inner_.authenticated(header); }

  /// Waits for the submissions under way, then ends the pool's threads: after the network threads stopped, so that no
  /// thread but the caller's is left to take a late stop signal.
  void join() { pool_.join(); }
  /// Submissions being checked or waiting now.
  int in_flight() const { return in_flight_.load(); }

 private:
  RoutedHandler& inner_;
  AdmissionOptions opt_;
  boost::asio::thread_pool pool_;
  std::atomic<int> in_flight_{0};
};

}  // namespace tessera::server
