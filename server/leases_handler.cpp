#include "server/leases_handler.h"

#include "protocol/tile_log.h"

#include <spdlog/spdlog.h>

#include <algorithm>
#include <charconv>
#include <future>
#include <memory>
#include <mutex>
#include <optional>

namespace tessera::server {

using protocol::ApiError;
using protocol::Endpoint;

LeasesHandler::LeasesHandler(Scheduler& scheduler, JobService& jobs, Metrics& metrics, ClockMs clock, FarmEvents& events,
                             LeaseWaiters& waiters, Background background)
    : sched_(scheduler), jobs_(jobs), metrics_(metrics), clock_(std::move(clock)), events_(events), waiters_(waiters),
      background_(at_once_if_empty(std::move(background))) {}

HttpResponse LeasesHandler::handle(const protocol::RouteMatch& route, HttpRequest& req, const Caller& /*caller*/) {
  const Endpoint endpoint = route.endpoint();
  const std::string& id = route.param;
  const unsigned v = req.version();
  switch (endpoint) {
    case Endpoint::worker_lease:
    case Endpoint::lease_result: {
      std::promise<HttpResponse> answer;
      std::future<HttpResponse> answered = answer.get_future();
      const Answer done = [&answer](HttpResponse res, std::exception_ptr refusal) {
        if (refusal) answer.set_exception(refusal);
        else answer.set_value(std::move(res));
      };
      if (endpoint == Endpoint::worker_lease) lease(id, req, done);
      else result(id, req, done);
      return answered.get();
    }
    case Endpoint::lease_heartbeat: return heartbeat(id, req);
    case Endpoint::lease_fail: {
      const protocol::FailReport report = protocol::parse_fail_report(req.body());
      require_holder(id, req);
      jobs_.record_failure(id, report);
      return json_response(http::status::ok, protocol::FailAnswer{}, v);
    }
    case Endpoint::lease_release:
      protocol::parse_empty_request(req.body());
      require_holder(id, req);
      if (!sched_.release(id)) throw ApiError(404, "unknown lease " + id);
      spdlog::debug("lease {}: released", id);
      return json_response(http::status::ok, protocol::ReleaseAnswer{}, v);
    case Endpoint::lease_state:
      require_holder(id, req);
      return bytes_response(jobs_.lease_state(id), "image/x-exr", v);
    default: break;
  }
  throw ApiError(404, "no such endpoint");
}

void LeasesHandler::lease(const std::string& worker, HttpRequest& req, Answer answer) {
  const unsigned version = req.version();
  const protocol::LeaseRequest asked = protocol::parse_lease_request(req.body());  // before a tile is taken
  require_worker(worker, req);
  if (std::optional<std::string> leased = try_lease(worker, asked))
    return answer(bytes_response(std::move(*leased), "application/json", version), nullptr);
  if (asked.wait_ms <= 0) return answer(HttpResponse{http::status::no_content, version}, nullptr);
  // A held request's answer says how long it was held (the API counts its time apart from the route's service time).
  const auto held_since = std::chrono::steady_clock::now();
  const auto no_work = [version, answer, held_since] {
    HttpResponse res{http::status::no_content, version};
    const auto held = std::chrono::duration_cast<std::chrono::milliseconds>(std::chrono::steady_clock::now() - held_since);
    res.set(protocol::kHeldMsHeader, std::to_string(held.count()));
    answer(std::move(res), nullptr);
  };
  // Held until a tile becomes leasable for this worker (one woken per such tile), the wait is over, or the coordinator
  // stops; every end is a 204. A woken worker asks again at once and takes its lease on a fresh request: a tile is
  // never granted to a held request whose worker may have gone meanwhile (stopped or killed while it waited).
  waiters_.hold(held_since + std::chrono::milliseconds(asked.wait_ms),
                [this, worker, no_work](int woken) {
                  if (sched_.leasable_tiles(worker) <= woken) return false;
                  no_work();
                  return true;
                },
                no_work);
}

std::optional<std::string> LeasesHandler::try_lease(const std::string& worker, const protocol::LeaseRequest& asked,
                                                    std::function<void()>* leased_event) {
  const AcquireResult r = sched_.acquire(worker);
  if (r.status == AcquireResult::unknown_worker) throw ApiError(404, "unknown worker " + worker + ": register again");
  if (r.status == AcquireResult::no_work) return std::nullopt;
  const Lease l = jobs_.with_state(r.lease);
  spdlog::debug("job {} tile {} worker {}: leased as {}", l.job, l.tile, l.worker, l.id);
  // queued -> running at the first lease (the snapshot, which lists the job's workers, only then); its image is
  // made ready for the tiles to come
  if (!events_.published(l.job, r.job_state))
    if (const auto s = sched_.job(l.job)) {
      if (s->state == protocol::JobState::running) jobs_.prepare_image(l.job);
      events_.job_if_state_changed(*s);
      if (s->sequence)  // a frame's first lease may start its sequence
        if (const auto seq = sched_.job(*s->sequence)) events_.job_if_state_changed(*seq);
    }
  auto event = [this, l] { events_.tile(protocol::events::kTileLeased, {l.job, l.tile, l.worker, l.id, std::nullopt}); };
  if (leased_event) *leased_event = std::move(event);
  else event();
  // The spec of a job the worker does not hold comes with the lease, saving it a GET of the spec per job.
  std::optional<std::string> spec;
  if (asked.known_jobs && std::find(asked.known_jobs->begin(), asked.known_jobs->end(), l.job) == asked.known_jobs->end()) {
    try {
      spec = jobs_.spec_json(l.job);
    } catch (const ApiError& e) {  // purged since the grant: the lease goes out bare, and the worker's GET says why
      spdlog::debug("lease {}: sent without its job's spec: {}", l.id, e.what());
    }
  }
  return protocol::lease_answer_text(l, spec ? &*spec : nullptr);
}

HttpResponse LeasesHandler::heartbeat(const std::string& lease, HttpRequest& req) {
  const uint64_t rays = protocol::parse_heartbeat_report(req.body()).rays;
  require_holder(lease, req);
  const HeartbeatResult h = sched_.heartbeat(lease, rays);
  if (h.status == HeartbeatResult::unknown) throw ApiError(404, "unknown lease " + lease);
  if (h.status == HeartbeatResult::gone)
    throw ApiError(410, "lease " + lease + " was revoked or expired: stop rendering this tile");
  metrics_.add_rays(rays, clock_());
  return json_response(http::status::ok, protocol::HeartbeatAnswer{h.deadline_ms}, req.version());
}

void LeasesHandler::require_worker(const std::string& worker, const HttpRequest& req) {
  const std::string_view secret = req[protocol::kWorkerSecretHeader];
  switch (sched_.check_worker(worker, secret)) {
    case WorkerCheck::ok: return;
    case WorkerCheck::unknown_lease:
    case WorkerCheck::unknown_worker: throw ApiError(404, "unknown worker " + worker + ": register again");
    case WorkerCheck::wrong_secret: break;
  }
  refuse_identity(secret.empty() ? "a request acting as worker " + worker + " must carry its secret (" +
                                        protocol::kWorkerSecretHeader + ", from its registration)"
                                  : std::string(protocol::kWorkerSecretHeader) + " is not the secret of worker " + worker);
}

void LeasesHandler::require_holder(const std::string& lease, const HttpRequest& req, std::string* holder_out) {
  const std::string_view secret = req[protocol::kWorkerSecretHeader];
  std::string holder;
  switch (sched_.check_lease_holder(lease, secret, &holder)) {
    case WorkerCheck::ok:
      if (holder_out) *holder_out = std::move(holder);
      return;
    case WorkerCheck::unknown_lease: throw ApiError(404, "unknown lease " + lease);
    case WorkerCheck::unknown_worker:
      throw ApiError(404, "lease " + lease + " belongs to worker " + holder + ", which this coordinator does not know: "
                          "register again");
    case WorkerCheck::wrong_secret: break;
  }
  refuse_identity(secret.empty() ? "lease " + lease + " is worker " + holder + "'s: a request on it must carry its "
                                        "secret (" + protocol::kWorkerSecretHeader + ", from its registration)"
                                  : "lease " + lease + " is worker " + holder + "'s, and " +
                                        protocol::kWorkerSecretHeader + " is not its secret");
}

void LeasesHandler::refuse_identity(const std::string& why) {
  // The sentence names ids, never a secret; a flood of refusals logs 10 lines a minute.
  uint64_t left_out = 0;
  if (refusal_log_.allow(left_out)) spdlog::warn("403 {}{}", why, LogLimit::left_out_note(left_out, "refusals"));
  throw ApiError(403, why);
}

void LeasesHandler::handle_async(const protocol::RouteMatch& route, HttpRequest& req, const Caller& caller, Answer answer) {
  const Endpoint endpoint = route.endpoint();
  const std::string& id = route.param;
  if (endpoint != Endpoint::lease_result && endpoint != Endpoint::worker_lease)
    return ResourceHandler::handle_async(route, req, caller, std::move(answer));
  try {
    if (endpoint == Endpoint::worker_lease) lease(id, req, answer);
    else result(id, req, answer);
  } catch (...) {
    answer(HttpResponse{}, std::current_exception());
  }
}

void LeasesHandler::result(const std::string& lease, HttpRequest& req, Answer answer) {
  uint64_t rays = 0;
  if (const auto h = req[protocol::kRaysHeader]; !h.empty()) {
    const auto [ptr, ec] = std::from_chars(h.data(), h.data() + h.size(), rays);
    if (ec != std::errc() || ptr != h.data() + h.size())
      throw ApiError(400, std::string(protocol::kRaysHeader) + " must be a non-negative integer (got '" + std::string(h) + "')");
  }
  std::vector<std::string> log = protocol::parse_tile_log_header(req[protocol::kTileLogHeader]);
  const std::optional<protocol::LeaseRequest> next = protocol::parse_next_lease_header(req[protocol::kNextLeaseHeader]);
  std::string worker;
  require_holder(lease, req, &worker);
  const unsigned version = req.version();
  // The worker's next lease, granted as the lease route grants one (no wait: a worker told "none" asks the lease
  // route). Granted on this thread once the tile is stored, so that the answer goes out as soon as the flush that
  // makes the upload durable is done, with no second turn in the handlers' queue; when that flush comes first (or
  // the upload is a duplicate), granted after it instead, off the thread that acknowledges commits, which a grant may
  // wait for. The upload's answer always follows its flush, and the lease's tile_leased event its tile_done.
  struct Grant {
    std::optional<std::string> text;  // the lease answer, none when no tile was leasable
    std::function<void()> event;      // its tile_leased event
  };
  struct NextLease {
    std::mutex mu;
    bool granting = false;                 // this thread took the grant
    bool granted = false;                  // ... and made it
    std::optional<UploadOutcome> outcome;  // the upload's, once durable
    Grant lease;
  };
  const auto state = std::make_shared<NextLease>();
  const auto grant = [this, worker, next] {
    Grant g;
    try {
      g.text = try_lease(worker, *next, &g.event);
    } catch (const std::exception& e) {  // forgotten meanwhile: its next lease request hears why
      spdlog::debug("worker {}: no next lease with its upload: {}", worker, e.what());
    }
    return g;
  };
  const auto respond = [answer, version](UploadOutcome o, const Grant& g) {
    if (g.event) g.event();
    answer(bytes_response(protocol::result_answer_text(o, g.text ? &*g.text : nullptr), "application/json", version),
           nullptr);
  };
  std::function<void()> stored;
  if (next)
    stored = [state, grant, respond] {
      {
        std::lock_guard lock(state->mu);
        if (state->outcome) return;  // durable already: the grant follows the answer's outcome
        state->granting = true;
      }
      Grant g = grant();
      std::optional<UploadOutcome> outcome;
      {
        std::lock_guard lock(state->mu);
        state->granted = true;
        outcome = state->outcome;
        if (!outcome) state->lease = std::move(g);
      }
      if (outcome) respond(*outcome, g);
    };
  jobs_.accept_tile(
      lease, req.body(), rays, std::move(log),
      [this, answer, version, next, state, grant, respond](UploadOutcome o, std::exception_ptr refusal) {
        if (refusal) return answer(HttpResponse{}, refusal);
        if (!next || o == UploadOutcome::discarded)
          return answer(json_response(o == UploadOutcome::discarded ? http::status::gone : http::status::ok,
                                      protocol::ResultAnswer{o, std::nullopt}, version),
                        nullptr);
        Grant g;
        {
          std::lock_guard lock(state->mu);
          state->outcome = o;
          if (state->granting && !state->granted) return;  // the uploading thread answers once it has the lease
          if (!state->granting) {
            background_([grant, respond, o] { respond(o, grant()); });
            return;
          }
          g = std::move(state->lease);
        }
        respond(o, g);
      },
      stored);
}

}  // namespace tessera::server
