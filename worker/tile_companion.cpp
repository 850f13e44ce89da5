#include "worker/tile_companion.h"

#include "protocol/headers.h"
#include "protocol/routes.h"

#include <nlohmann/json.hpp>
#include <spdlog/spdlog.h>

#include <utility>

namespace tessera::worker {

using namespace std::chrono_literals;
namespace routes = protocol::routes;

TileCompanion::TileCompanion(client::HttpClient& http, std::string prefix, std::string lease, std::string worker_secret,
                             std::chrono::milliseconds period, std::chrono::milliseconds first_beat,
                             RenderSignals& signals, const std::atomic<int>& stop_requests,
                             std::function<std::optional<PrefetchedLease>()> ask_lease)
    : http_(http), prefix_(std::move(prefix)), lease_(std::move(lease)), secret_(std::move(worker_secret)), period_(period),
      first_beat_(first_beat),
      cancel_(signals.cancel), reason_(signals.reason), rays_(signals.rays), stop_requests_(stop_requests),
      ask_lease_(std::move(ask_lease)), thread_([this] { run(); }) {}

TileCompanion::~TileCompanion() { stop(); }

void TileCompanion::ask_next_lease() {
  {
    std::lock_guard lock(mutex_);
    if (asked_) return;
    asked_ = true;
  }
  cv_.notify_all();
}

bool TileCompanion::has_next_lease() {
  std::unique_lock lock(mutex_);
  cv_.wait(lock, [&] { return !asked_ || answered_ || done_; });
  return next_.has_value();
}

std::optional<PrefetchedLease> TileCompanion::finish() {
  stop();
  std::lock_guard lock(mutex_);
  return std::move(next_);
}

std::optional<std::chrono::steady_clock::time_point> TileCompanion::last_beat() {
  std::lock_guard lock(mutex_);
  return last_beat_;
}

void TileCompanion::stop() {
  {
    std::lock_guard lock(mutex_);
    if (done_) return;
    done_ = true;
  }
  cv_.notify_all();
  thread_.join();
}

void TileCompanion::run() noexcept {
  try {
    auto next = std::chrono::steady_clock::now() + first_beat_;
    uint64_t sent_rays = 0;
    bool stop_noted = false, fetched = false;
    std::unique_lock lock(mutex_);
    for (;;) {
      cv_.wait_for(lock, 100ms, [&] { return done_ || (asked_ && !fetched); });
      if (asked_ && !fetched) {  // even when the render ended meanwhile: the worker needs its next tile now
        fetched = true;
        lock.unlock();
        std::optional<PrefetchedLease> l = ask_lease_();
        lock.lock();
        if (l) next_ = std::move(*l);
        answered_ = true;
        cv_.notify_all();
        continue;
      }
      if (done_) break;
      if (stop_requests_.load() == 1 && !stop_noted) {
        stop_noted = true;
        spdlog::info("{}: asked to stop, finishing this tile first", prefix_);
      }
      if (stop_requests_.load() >= 2 && !cancel_.load()) {
        reason_.store(int(Stop::kShutdown));
        cancel_.store(true);
        spdlog::info("{}: asked to stop again, cancelling the render to hand the tile back", prefix_);
      }
      if (std::chrono::steady_clock::now() < next) continue;
      const std::optional<std::string> held = next_ ? std::optional<std::string>(next_->lease.id) : std::nullopt;
      lock.unlock();
      if (!cancel_.load()) {
        const uint64_t rays = rays_.load();
        if (!beat(lease_, nlohmann::json(protocol::HeartbeatReport{rays - sent_rays}).dump())) {
          reason_.store(int(Stop::kRevoked));
          cancel_.store(true);
        }
        sent_rays = rays;
      }
      const bool held_live = !held || beat(*held, "{}");
      next = std::chrono::steady_clock::now() + period_;
      lock.lock();
      if (held && next_) {
        if (held_live) {
          next_->beaten = std::chrono::steady_clock::now();
        } else if (next_->head) {  // its render, begun already, is stopped; the worker drops the tile
          next_->head->signals.reason.store(int(Stop::kRevoked));
          next_->head->signals.cancel.store(true);
        } else {
          next_.reset();  // revoked or expired meanwhile: the worker asks again
        }
      }
    }
  } catch (const std::exception& e) {
    spdlog::error("{}: heartbeat thread stopped: {}", prefix_, e.what());
  } catch (...) {
    spdlog::error("{}: heartbeat thread stopped by an unknown exception", prefix_);
  }
  std::lock_guard lock(mutex_);
  answered_ = true;  // whatever was asked gets no answer now: has_next_lease() waits no longer
  cv_.notify_all();
}

bool TileCompanion::beat(const std::string& lease, const std::string& body) {
  try {
    client::HttpRequest req;
    req.method = "POST";
    req.target = routes::lease_heartbeat(lease);
    req.body = body;
    req.content_type = "application/json";
    req.headers[protocol::kWorkerSecretHeader] = secret_;
    const client::HttpResponse r = http_.send(req);
    if (r.status == 200) {
      if (lease == lease_) {
        std::lock_guard lock(mutex_);
        last_beat_ = std::chrono::steady_clock::now();
      }
      return true;
    }
    const std::string which = lease == lease_ ? "heartbeat" : "heartbeat of the next lease " + lease;
    if (r.status == 410 || r.status == 404 || r.status == 403) {
      spdlog::info("{}: {} answered {} ({}), {}", prefix_, which, r.status, r.error_text(),
                   lease == lease_ ? "cancelling the render" : "dropping that lease");
      return false;
    }
    spdlog::warn("{}: {} answered {}: {}", prefix_, which, r.status, r.error_text());
  } catch (const client::TransportError& e) {
    spdlog::warn("{}: {} failed (keeps rendering): {}", prefix_, lease == lease_ ? "heartbeat" : "heartbeat of " + lease,
                 e.what());
  }
  return true;
}

}  // namespace tessera::worker
