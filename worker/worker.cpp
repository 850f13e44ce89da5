#include "worker/worker.h"

#include "client/backoff.h"
#include "core/image/image.h"
#include "core/render/render.h"
#include "core/render/render_state.h"
#include "failpoint/failpoint.h"
#include "protocol/messages.h"
#include "protocol/routes.h"
#include "protocol/tile.h"
#include "protocol/tile_log.h"
#include "worker/arena_pinning.h"
#include "worker/asset_cache.h"
#include "worker/job_scenes.h"
#include "worker/prefetched_lease.h"
#include "worker/recent_log.h"
#include "worker/render_signals.h"
#include "worker/tile_companion.h"
#include "worker/tile_upload.h"
#include "worker/upload_queue.h"

#include <spdlog/spdlog.h>
#include <tbb/global_control.h>
#include <tbb/task_arena.h>

#include <unistd.h>

#include <exception>
#include <future>
#include <memory>
#include <mutex>
#include <optional>
#include <thread>

namespace tessera::worker {

using nlohmann::json;
using namespace std::chrono_literals;
using protocol::JobSpec;
using protocol::Lease;
using protocol::Registration;
namespace routes = protocol::routes;

namespace {

// The coordinator refused the worker token (401/403): retrying cannot help, the worker stops with this message.
struct AccessDenied : std::runtime_error {
  using std::runtime_error::runtime_error;
};

// A tile's preparation was interrupted by a cancel (lease revoked or second stop request).
struct Interrupted : std::runtime_error {
  using std::runtime_error::runtime_error;
};

std::string default_name() {
  char host[256] = {};
  if (::gethostname(host, sizeof host - 1) != 0) std::snprintf(host, sizeof host, "worker");
  return std::string(host) + "-" + std::to_string(::getpid());
}

class Worker {
  static constexpr uint64_t kMaxResponse = uint64_t(2) << 30;  // blobs and specs
  static constexpr size_t kFailureLogLines = 20;       // log lines sent with a failure report
  static constexpr size_t kFailureLogLineBytes = 400;  // each cut to this (the coordinator takes up to 1000)
  static_assert(kFailureLogLines <= protocol::kMaxFailureLogLines && kFailureLogLineBytes <= protocol::kMaxFailureLogLineBytes);

  // Heartbeats must fail fast enough to be retried within a lease: at most 2 s to connect and 5 s per phase.
  static client::HttpTimeouts heartbeat_timeouts(const client::HttpTimeouts& t) {
    return client::HttpTimeouts{std::min<std::chrono::milliseconds>(t.connect, 2000ms), std::min<std::chrono::milliseconds>(t.write, 5000ms),
                        std::min<std::chrono::milliseconds>(t.read, 5000ms)};
  }

 public:
  Worker(const WorkerOptions& opt, const std::atomic<int>& stop)
      : opt_(opt), stop_(stop), url_(client::parse_http_url(opt.coordinator)), http_(url_, opt.timeouts, kMaxResponse, opt.tls),
        heartbeat_http_(url_, heartbeat_timeouts(opt.timeouts), kMaxResponse, opt.tls),
        upload_http_(url_, opt.timeouts, kMaxResponse, opt.tls),
        scenes_(opt.cache_dir.empty() ? default_cache_dir() : opt.cache_dir, opt.scene_cache_jobs, opt.image_cache_bytes,
                opt.asset_limits),
        idle_(std::min<std::chrono::milliseconds>(100ms, opt.max_idle_wait), opt.max_idle_wait),
        retry_(200ms, opt.max_retry_wait) {
    name_ = opt.name.empty() ? default_name() : opt.name;
    threads_ = opt.threads > 0 ? opt.threads : int(std::max(1u, std::thread::hardware_concurrency()));
    arena_.initialize(threads_);
    if (!opt.cpus.empty()) pinning_.emplace(arena_, opt.cpus);
    http_.set_bearer_token(opt.token);
    heartbeat_http_.set_bearer_token(opt.token);
    upload_http_.set_bearer_token(opt.token);
  }

  WorkerStats run() {
    spdlog::info("worker {} starting: coordinator {}, {} threads, cache {}", name_, url_.to_string(), threads_,
                 scenes_.cache_dir().string());
    if (opt_.preload) scenes_.preload(*opt_.preload);
    std::optional<PrefetchedLease> next;  // asked for while the previous tile rendered
    while (!stopping()) {
      try {
        if (id_.empty() && !register_worker()) continue;
        std::optional<PrefetchedLease> lease = std::exchange(next, std::nullopt);
        if (!lease) lease = lease_from_upload();
        if (!lease && !stopping()) {
          std::optional<protocol::LeaseAnswer> asked = request_lease();
          if (asked) lease = PrefetchedLease::granted(std::move(*asked));
        }
        if (!lease) continue;
        if (stopping()) {
          drop_head_start(*lease);
          release(lease->lease, prefix(lease->lease));
          break;
        }
        next = process(lease->lease, lease->beaten, std::move(lease->head), std::move(lease->spec));
      } catch (const AccessDenied&) {
        throw;
      } catch (const std::exception& e) {
        // Unexpected (a bug or resource exhaustion): log it, wait, carry on rather than die.
        spdlog::error("worker {}: {}", id_.empty() ? name_ : id_, e.what());
        client::sleep_unless(retry_.next(), [&] { return stopping(); });
      }
    }
    if (next) {  // asked to stop while holding the next tile: hand it back
      drop_head_start(*next);
      release(next->lease, prefix(next->lease));
    }
    uploads_.wait_idle();  // the last tile's upload finishes (a second stop request cuts its retries short)
    if (std::optional<PrefetchedLease> late = lease_from_upload()) release(late->lease, prefix(late->lease));
    std::lock_guard lock(stats_mutex_);
    stats_.scenes_preloaded = scenes_.preloads_used();
    spdlog::info("worker {} stopping: {} tiles uploaded, {} dropped, {} failed, {} released", id_.empty() ? name_ : id_,
                 stats_.tiles_uploaded, stats_.tiles_dropped, stats_.tiles_failed, stats_.tiles_released);
    return stats_;
  }

 private:
  // Also notes when this worker first saw a stop request (the signal handler only counts them).
  bool stopping() const {
    if (stop_.load() == 0) return false;
    if (stop_seen_.load() == std::chrono::steady_clock::time_point{}) {
      auto none = std::chrono::steady_clock::time_point{};
      stop_seen_.compare_exchange_strong(none, std::chrono::steady_clock::now());
    }
    return true;
  }

  // Why the upload of a tile whose render ended at `rendered` is to be given up now ("": keep trying). Only a stopping
  // worker gives up: on a second stop request, once the lease has run out on the coordinator (`lease_end`, as far as
  // the worker knows: a lease's length after its last answered heartbeat), or --stop-timeout after the stop request
  // or `rendered`, whichever is later.
  std::string upload_give_up(std::chrono::steady_clock::time_point rendered,
                             std::chrono::steady_clock::time_point lease_end) const {
    if (stop_.load() >= 2) return "asked to stop again";
    if (!stopping()) return {};
    const auto now = std::chrono::steady_clock::now();
    const auto seconds = [](auto d) { return std::chrono::duration<double>(d).count(); };
    if (now >= lease_end)
      return fmt::format("stopping, and its lease ran out {:.1f} s ago (a lease lasts {:.1f} s after its last answered "
                         "heartbeat); the coordinator gives the tile to another worker",
                         seconds(now - lease_end), seconds(lease_length_));
    if (now - std::max(rendered, stop_seen_.load()) >= opt_.stop_timeout)
      return fmt::format("stopping, and the coordinator has not taken it within --stop-timeout ({:.1f} s)",
                         seconds(opt_.stop_timeout));
    return {};
  }

  // Counts a tile's outcome (from the render loop or the upload thread).
  void count(int64_t WorkerStats::*outcome) {
    std::lock_guard lock(stats_mutex_);
    ++(stats_.*outcome);
  }

  // Notes a transport failure (loudly for the first of an outage) and waits before the next attempt.
  void coordinator_down(const std::string& what, const client::TransportError& e) {
    if (!down_) spdlog::warn("worker {}: coordinator unreachable ({}): {}; retrying with backoff", name_, what, e.what());
    else spdlog::debug("worker {}: still unreachable: {}", name_, e.what());
    down_ = true;
    client::sleep_unless(retry_.next(), [&] { return stopping(); });
  }
  // An answer came; `reset_backoff` false for one that says to come back later (5xx: busy, disk full), whose retries
  // keep backing off.
  void coordinator_up(bool reset_backoff = true) {
    if (down_) spdlog::info("worker {}: coordinator reachable again", name_);
    down_ = false;
    if (reset_backoff) retry_.reset();
  }

  // Throws AccessDenied for 401/403: the token is missing or wrong, which no retry fixes.
  void refuse_if_denied(const client::HttpResponse& r, const char* what) const {
    if (r.status == 401 || r.status == 403)
      throw AccessDenied(std::string(what) + " refused with " + std::to_string(r.status) + ": " + r.error_text() +
                         (opt_.token.empty() ? " (no token given: use --token-file or TESSERA_WORKER_TOKEN)"
                                             : " (check --token-file or TESSERA_WORKER_TOKEN)"));
  }

  bool register_worker() {
    const json body = protocol::WorkerHello{name_, threads_, TESSERA_VERSION, opt_.tags};
    try {
      const client::HttpResponse r = http_.send("POST", routes::workers(), body.dump());
      coordinator_up(r.status < 500);
      if (r.status == 201 || r.status == 200) {
        const auto reg = protocol::parse_answer<Registration>(r.body, "registration");
        id_ = reg.id;
        secret_ = reg.secret;
        heartbeat_period_ = std::chrono::milliseconds(std::max<int64_t>(100, int64_t(reg.heartbeat_seconds * 1000)));
        lease_length_ = std::chrono::milliseconds(int64_t(reg.lease_seconds * 1000));
        spdlog::info("worker {} registered as {} (lease {}s, heartbeat {}s)", name_, id_, reg.lease_seconds,
                     reg.heartbeat_seconds);
        return true;
      }
      refuse_if_denied(r, "registration");
      spdlog::error("worker {}: registration refused with {}: {}", name_, r.status, r.error_text());
    } catch (const client::TransportError& e) {
      coordinator_down("register", e);
      return false;
    }
    client::sleep_unless(retry_.next(), [&] { return stopping(); });
    return false;
  }

  // One lease request's round trip, kept as a moving average: a render asks for its successor when it has about
  // this long (times a margin) left.
  void note_lease_round_trip(std::chrono::steady_clock::time_point t0) {
    const double ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
    const double old = lease_rtt_ms_.load();
    lease_rtt_ms_.store(old <= 0 ? ms : 0.8 * old + 0.2 * ms);
  }

  // The next lease, asked for from the tile companion's thread near the end of a render (on its connection): only a
  // granted lease is kept; anything else (no work, an error) leaves the asking to the render loop, as before. When
  // the tile can be rendered at once (its job's scene is built, it continues from no stored state, it fits), its
  // render is begun on the arena so that threads going idle at the current tile's end take its work.
  std::optional<PrefetchedLease> prefetch_lease(client::HttpClient& http, const std::string& pfx) {
    try {
      const auto t0 = std::chrono::steady_clock::now();
      const client::HttpResponse r = http.send(as_worker("POST", routes::worker_lease(id_), lease_request_body()));
      note_lease_round_trip(t0);
      if (r.status != 200) return std::nullopt;
      auto answer = protocol::parse_answer<protocol::LeaseAnswer>(r.body, "lease");
      PrefetchedLease next = PrefetchedLease::granted(std::move(answer));
      next.head = head_start(next.lease);
      spdlog::info("{}: next lease {} (tile {} of job {}) granted while rendering{}", pfx, next.lease.id,
                   next.lease.tile, next.lease.job, next.head ? ", its render begun" : "");
      return next;
    } catch (const std::exception& e) {
      spdlog::debug("{}: asking for the next lease failed: {}", pfx, e.what());
      return std::nullopt;
    }
  }

  // The options a lease's tile renders with (the same whether it is begun ahead or not).
  RenderOptions render_options(const Lease& l, const PreparedJob& job, RenderSignals& signals,
                               const StoredRender* previous) {
    RenderOptions ro;
    job.sampling.apply_to(ro);
    ro.seed = l.seed;
    ro.spp = l.spp;
    ro.window = l.window;
    // Small thread tiles: a farm tile is one worker's whole unit of work (pixels do not depend on this split).
    ro.tile_size = 8;
    ro.cancel = &signals.cancel;
    // Near the end of the render (about two and a half lease round trips left, at the pace so far) the next lease is
    // asked for, so the threads need not wait for it; it is held only for that short tail.
    const double lead_s = std::max(0.002, 2.5e-3 * lease_rtt_ms_.load());
    ro.progress = [&signals, lead_s, this](const RenderProgress& p) {
      signals.rays.store(p.rays);
      if (p.tiles_done > 0 && !stopping() &&
          p.seconds * double(p.tiles_total - p.tiles_done) / double(p.tiles_done) <= lead_s)
        signals.want_next();
    };
    ro.keep_state = l.resumable;
    ro.previous = previous;
    return ro;
  }

  // Where tests fail a tile's render, or hold it until released (a pause ends when the tile is cancelled, as a long
  // render would): just before the render, whether it is begun ahead (on a thread of the arena) or not.
  static void before_render([[maybe_unused]] int64_t tile, [[maybe_unused]] RenderSignals& signals) {
    TESSERA_FAIL_POINT_CANCELLABLE("worker.render", [&] { return signals.cancel.load(); });
    TESSERA_FAIL_POINT_RETURN("worker.render.fail_tiles", [&](const std::string& tiles) {
      for (size_t i = 0; i < tiles.size();) {
        const size_t comma = std::min(tiles.find(',', i), tiles.size());
        if (tiles.substr(i, comma - i) == std::to_string(tile))
          throw std::runtime_error("fail point worker.render.fail_tiles: tile " + std::to_string(tile) +
                                   " fails on every worker");
        i = comma + 1;
      }
    });
  }

  // Begins the render of a tile just leased (see prefetch_lease), or gives nothing when it cannot start now.
  std::shared_ptr<HeadStart> head_start(const Lease& l) {
    // A worker with one thread has no second thread to fill a tail with.
    if (threads_ < 2 || l.state_spp > 0 || stopping()) return nullptr;
    std::shared_ptr<const PreparedJob> job = scenes_.find(l.job);
    if (!job || !PixelWindow{0, 0, job->loaded.scene.width, job->loaded.scene.height}.contains(l.window)) return nullptr;
    // However it is dropped from here on, its task has ended before it goes.
    std::shared_ptr<HeadStart> head(new HeadStart, [this](HeadStart* h) {
      if (h->enqueued) wait_for(*h);
      delete h;
    });
    head->scene = std::move(job);
    const RenderOptions ro = render_options(l, *head->scene, head->signals, nullptr);
    // Enqueued into the arena (this thread does not wait): a thread of it takes the task once it has no other work,
    // i.e. when the current tile's thread tiles run out, and puts the render into the group, which the render loop
    // then waits for, helping.
    arena_.enqueue([h = head.get(), ro, tile = l.tile] {
      h->group.run([h, ro, tile] {
        try {
          before_render(tile, h->signals);
          h->result = render(h->scene->loaded.scene, ro);
        } catch (...) {
          h->error = std::current_exception();
        }
      });
      std::lock_guard lock(h->mutex);
      h->submitted = true;
      h->cv.notify_all();
    });
    head->enqueued = true;
    return head;
  }

  // Waits for a begun render (also when it is to be dropped: its task must end before it goes), helping with it. Not
  // isolated, or this thread could not help (the render's tasks come from another thread); so while it waits it may
  // also take up the render begun for the tile after (TBB hands a waiting thread any task of its arena), and this
  // tile then waits for that one too: farm tests hold at worker.render only renders begun after a render not begun
  // ahead.
  void wait_for(HeadStart& head) {
    {
      std::unique_lock lock(head.mutex);
      head.cv.wait(lock, [&] { return head.submitted; });
    }
    arena_.execute([&] { head.group.wait(); });
  }

  // Stops the render begun for a lease that is handed back instead.
  void drop_head_start(PrefetchedLease& next) {
    if (!next.head) return;
    next.head->signals.cancel.store(true);
    next.head.reset();  // waits for the task
  }

  // A request that acts as this worker: it carries the worker's secret. The secret and id change only in
  // register_worker(), on the render loop's thread while no tile companion runs (the upload thread copies the secret).
  client::HttpRequest as_worker(std::string method, std::string target, std::string body = {}) const {
    client::HttpRequest req{std::move(method), std::move(target), std::move(body), "application/json", {}};
    req.headers[protocol::kWorkerSecretHeader] = secret_;
    return req;
  }

  // A lease request: the jobs whose scenes are built here, so that a lease of any other job brings its spec, and how
  // long the coordinator may hold the request for work (sent as a lease request's body, or with an upload).
  protocol::LeaseRequest lease_request(std::chrono::milliseconds wait = 0ms) {
    protocol::LeaseRequest req;
    req.known_jobs = scenes_.jobs();  // most recently used first: beyond the protocol's limit, the older ones go
    if (req.known_jobs->size() > protocol::kMaxKnownJobs) req.known_jobs->resize(protocol::kMaxKnownJobs);
    req.wait_ms = std::min<int64_t>(wait.count(), protocol::kMaxLeaseWaitMs);
    return req;
  }
  std::string lease_request_body(std::chrono::milliseconds wait = 0ms) { return json(lease_request(wait)).dump(); }

  // The lease the last upload asked for, once that upload has ended (settled or given up): nothing when it did not
  // ask, or its answer carried none (the worker then asks the lease route).
  std::optional<PrefetchedLease> lease_from_upload() {
    if (!upload_lease_.valid()) return std::nullopt;
    std::optional<PrefetchedLease> l = upload_lease_.get();
    if (!l) return std::nullopt;
    if (upload_lease_worker_ != id_) {  // registered again meanwhile: the lease is the old identity's and expires
      spdlog::info("{}: granted to this worker's previous registration; left to expire", prefix(l->lease));
      return std::nullopt;
    }
    idle_.reset();
    spdlog::info("{}: granted with the upload of the previous tile", prefix(l->lease));
    return l;
  }

  // Asks for a lease, which the coordinator may hold for the idle backoff's next wait: a 204 before the wait is over
  // says that work came (or that the coordinator is stopping), and the worker asks again at once, so a job submitted
  // meanwhile starts without waiting for the next poll. (A round trip with a wait does not enter lease_rtt_ms_.)
  std::optional<protocol::LeaseAnswer> request_lease() {
    client::HttpResponse r;
    // Within half the read timeout, so that a held request never looks like a dead coordinator.
    const std::chrono::milliseconds wait = std::min(idle_.next(), opt_.timeouts.read / 2);
    const auto t0 = std::chrono::steady_clock::now();
    try {
      // A stop does not wait for the held request's end.
      r = http_.send(as_worker("POST", routes::worker_lease(id_), lease_request_body(wait)), [this] { return stopping(); });
    } catch (const client::RequestInterrupted&) {
      return std::nullopt;  // stopping: the coordinator forgets the request when the connection closes
    } catch (const client::TransportError& e) {
      coordinator_down("lease", e);
      return std::nullopt;
    }
    coordinator_up(r.status < 500);
    if (r.status == 200) {
      idle_.reset();
      return protocol::parse_answer<protocol::LeaseAnswer>(r.body, "lease");
    }
    if (r.status == 204) {  // the wait is over with no work, or work came before it was (then ask again at once)
      if (std::chrono::steady_clock::now() - t0 < wait) idle_.reset();
      return std::nullopt;
    }
    refuse_if_denied(r, "lease request");
    if (r.status == 404) {
      spdlog::info("worker {}: the coordinator does not know this worker, registering again", id_);
      id_.clear();
      return std::nullopt;
    }
    spdlog::warn("worker {}: lease request answered {}: {}", id_, r.status, r.error_text());
    client::sleep_unless(retry_.next(), [&] { return stopping(); });
    return std::nullopt;
  }

  std::string prefix(const Lease& l) const {
    return "worker=" + id_ + " job=" + l.job + " tile=" + std::to_string(l.tile) + " lease=" + l.id;
  }

  // GETs target (as this worker when `acting`), retrying transport errors and 5xx until it succeeds or
  // `interrupted` says to give up; 404 is Gone.
  std::string fetch(const std::string& target, const std::function<bool()>& interrupted, bool acting = false) {
    client::Backoff backoff(200ms, opt_.max_retry_wait);
    while (true) {
      if (interrupted()) throw Interrupted("interrupted while fetching " + target);
      try {
        const client::HttpResponse r = http_.send(acting ? as_worker("GET", target) : client::HttpRequest{"GET", target, {}, "application/json", {}});
        if (r.status == 200) return r.body;
        if (r.status == 404) throw Gone("GET " + target + ": not found (" + r.error_text() + ")");
        if (!r.retryable())
          throw std::runtime_error("GET " + target + " answered " + std::to_string(r.status) + ": " + r.error_text());
        spdlog::warn("GET {} answered {}: {}; retrying", target, r.status, r.error_text());
      } catch (const client::TransportError& e) {
        spdlog::warn("{}; retrying", e.what());
      }
      client::sleep_unless(backoff.next(), interrupted);
    }
  }

  // The job's scene, built once and kept for its later tiles; from the spec that came with the lease, if one did.
  std::shared_ptr<const PreparedJob> scene_for(const Lease& l, std::optional<JobSpec> sent, const std::string& pfx,
                                               const std::function<bool()>& interrupted) {
    if (auto s = scenes_.find(l.job)) return s;
    const auto t0 = std::chrono::steady_clock::now();
    const bool with_lease = sent.has_value();
    const JobSpec spec =
        with_lease ? std::move(*sent) : protocol::parse_answer<JobSpec>(fetch(routes::job_spec(l.job), interrupted), "job spec");
    const int preloaded = scenes_.preloads_used();
    auto prepared = scenes_.build(l.job, spec, [&](const std::string& h) { return fetch(routes::blob(h), interrupted); });
    const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    if (scenes_.preloads_used() > preloaded) {
      spdlog::info("{}: took the job's scene loaded at start (--preload) after {:.2f}s, spec {}", pfx, seconds,
                   with_lease ? "sent with the lease" : "fetched");
      return prepared;
    }
    spdlog::info("{}: built the job's scene in {:.2f}s ({} assets, {} image(s) taken already decoded{}, spec {})", pfx,
                 seconds, spec.assets.size(),
                 prepared->loaded.images_reused,
                 prepared->loaded.environment_reused ? ", the environment's sampling table kept" : "",
                 with_lease ? "sent with the lease" : "fetched");
    return prepared;
  }

  // Renders a leased tile (heartbeating it from `beaten`, its grant or last heartbeat; its render maybe begun ahead,
  // `head`; its job's spec when it came with the lease) and hands its upload to the upload thread; returns the next
  // lease when one was granted near the end of the render.
  std::optional<PrefetchedLease> process(const Lease& l, std::chrono::steady_clock::time_point beaten,
                                         std::shared_ptr<HeadStart> head, std::optional<JobSpec> spec) {
    const std::string pfx = prefix(l);
    spdlog::info("{}: leased window [{},{})x[{},{}) at {} spp{}", pfx, l.window.x0, l.window.x1, l.window.y0, l.window.y1,
                 l.spp, l.state_spp ? " continuing from " + std::to_string(l.state_spp) : std::string());
    RenderSignals own;
    RenderSignals& signals = head ? head->signals : own;
    std::optional<RenderResult> result;
    std::string failure;  // error to report through /fail
    int width = 0, height = 0;
    const auto since_beat = std::chrono::duration_cast<std::chrono::milliseconds>(std::chrono::steady_clock::now() - beaten);
    TileCompanion companion(heartbeat_http_, pfx, l.id, secret_, heartbeat_period_,
                            std::max<std::chrono::milliseconds>(0ms, heartbeat_period_ - since_beat), signals, stop_,
                            [this, pfx] { return prefetch_lease(heartbeat_http_, pfx); });
    signals.attach([&companion] { companion.ask_next_lease(); });
    struct Detach {
      RenderSignals& signals;
      ~Detach() { signals.attach({}); }
    } detach{signals};
    const auto finish = [&] {
      signals.attach({});
      return companion.finish();
    };
    {
      try {
        if (head) {
          wait_for(*head);
          if (head->error) std::rethrow_exception(head->error);
          width = head->scene->loaded.scene.width;
          height = head->scene->loaded.scene.height;
          result = std::move(head->result);
        } else {
          const auto scene = scene_for(l, std::move(spec), pfx, [&] { return signals.cancel.load(); });
          width = scene->loaded.scene.width;
          height = scene->loaded.scene.height;
          if (!PixelWindow{0, 0, width, height}.contains(l.window))
            throw std::runtime_error("tile window lies outside the " + std::to_string(width) + "x" +
                                     std::to_string(height) + " image");
          before_render(l.tile, signals);
          // A resumable job's tile rendered before (state_spp samples per pixel): continue from its exact sums.
          std::optional<StoredRender> previous;
          if (l.state_spp > 0)
            previous = stored_tile(l, scene->sampling.replicates, [&] { return signals.cancel.load(); });
          const RenderOptions ro = render_options(l, *scene, signals, previous ? &*previous : nullptr);
          // Isolated: while it waits for this tile's last thread tiles, the loop's thread takes none of a render
          // begun ahead (which may be held at a fail point), so this tile's upload never waits for the next tile.
          arena_.execute([&] { tbb::this_task_arena::isolate([&] { result = render(scene->loaded.scene, ro); }); });
        }
        if (result && result->cancelled) result.reset();
        else if (result && l.resumable) write_state_channels(result->state, result->image);
      } catch (const Interrupted&) {
        result.reset();
      } catch (const Gone& e) {
        spdlog::warn("{}: dropping the tile: {}", pfx, e.what());
        count(&WorkerStats::tiles_dropped);
        return finish();
      } catch (const std::exception& e) {
        failure = e.what();
      }
    }

    if (!failure.empty()) {
      std::optional<PrefetchedLease> next = finish();
      spdlog::error("{}: cannot render the tile: {}", pfx, failure);
      report_failure(l, pfx, failure);
      return next;
    }
    if (!result) {
      std::optional<PrefetchedLease> next = finish();
      if (signals.reason.load() == int(Stop::kShutdown)) {
        release(l, pfx);
      } else {
        spdlog::info("{}: lease revoked, tile dropped", pfx);
        count(&WorkerStats::tiles_dropped);
      }
      return next;
    }
    spdlog::info("{}: rendered in {:.3f}s ({} rays, {:.1f} ms of thread time not on this tile){}", pfx, result->seconds,
                 result->counters.rays, 1000.0 * result->idle_thread_seconds, head ? ", begun ahead" : "");
    // Encoded and sent while the next tile is leased and rendered; the companion heartbeats this lease (and the next
    // one) while the previous upload is still going, and a worker that dies here loses only leases, which expire.
    // The lease runs out a lease's length after its last answered heartbeat, known once the heartbeats stop (below).
    using LeaseEnd = std::atomic<std::chrono::steady_clock::time_point>;
    const auto lease_end = std::make_shared<LeaseEnd>(std::chrono::steady_clock::time_point::max());
    const auto rendered = std::chrono::steady_clock::now();
    // The upload carries the last lines logged about this lease, as a failure report does (within the upload's bounds).
    std::vector<std::string> log =
        recent_.log().lines_with(pfx + ":", protocol::kMaxTileLogLines, protocol::kMaxTileLogLineBytes);
    // A render that ended without the next lease in hand (none was asked for, or its request got none) asks for it
    // with the upload (docs/protocol.md, "One request per tile"); the loop then takes it from the upload's answer
    // before it asks the lease route. One that has it (the steady state: asked for near the render's end, so that its
    // render could begin on the threads this one leaves idle) asks for nothing more.
    signals.attach({});
    std::optional<protocol::LeaseRequest> ask;
    std::shared_ptr<std::promise<std::optional<PrefetchedLease>>> granted;
    if (!stopping() && !companion.has_next_lease()) {
      ask = lease_request();
      granted = std::make_shared<std::promise<std::optional<PrefetchedLease>>>();
      upload_lease_ = granted->get_future();
      upload_lease_worker_ = id_;
    }
    // The secret is copied: the worker may register again (with a new one) while this upload is under way.
    uploads_.post([this, l, secret = secret_, pfx, res = std::make_shared<RenderResult>(std::move(*result)), width,
                   height, lease_end, rendered, log = std::move(log), ask = std::move(ask), granted] {
      std::optional<PrefetchedLease> next;
      try {
        Delivery d = upload_tile(upload_http_, l, secret, pfx, *res, width, height, log, ask, opt_.max_retry_wait,
                                 [this, lease_end, rendered] { return upload_give_up(rendered, lease_end->load()); });
        if (d.next) next = PrefetchedLease::granted(std::move(*d.next));
        count(d.outcome == DeliveryOutcome::kUploaded ? &WorkerStats::tiles_uploaded
              : d.outcome == DeliveryOutcome::kFailed ? &WorkerStats::tiles_failed
                                                    : &WorkerStats::tiles_dropped);
      } catch (const std::exception& e) {
        spdlog::error("{}: upload stopped: {}; tile dropped", pfx, e.what());
        count(&WorkerStats::tiles_dropped);
      }
      if (granted) granted->set_value(std::move(next));
    });
    std::optional<PrefetchedLease> next = finish();  // heartbeats stop here
    lease_end->store(std::max(beaten, companion.last_beat().value_or(beaten)) + lease_length_);
    return next;
  }

  // The lease's tile as the coordinator stored it (GET /v1/leases/{lease}/state): its pixels and exact sums.
  StoredRender stored_tile(const Lease& l, uint32_t replicates, const std::function<bool()>& interrupted) {
    ExrImage exr = decode_exr(fetch(routes::lease_state(l.id), interrupted, /*acting=*/true));
    if (!(exr.data_window == l.window)) throw std::runtime_error("the stored state of the tile covers another window");
    StoredRender stored{std::move(exr.pixels), {}};
    stored.state = read_state_channels(stored.image, replicates);
    if (!stored.state.exact()) throw std::runtime_error("the stored state of the tile has no exact sums");
    return stored;
  }

  // Posts a small JSON message about a lease, retrying briefly; the lease expires anyway if this never arrives.
  bool post_lease_message(const std::string& pfx, const std::string& action, const std::string& target,
                          const json& body, int attempts) {
    client::Backoff backoff(100ms, 1000ms);
    for (int i = 0; i < attempts; ++i) {
      try {
        const client::HttpResponse r = http_.send(as_worker("POST", target, body.dump()));
        if (r.status == 200) return true;
        if (!r.retryable()) {
          spdlog::warn("{}: {} answered {}: {}", pfx, action, r.status, r.error_text());
          return false;
        }
      } catch (const client::TransportError& e) {
        spdlog::warn("{}: {} failed: {}", pfx, action, e.what());
      }
      std::this_thread::sleep_for(backoff.next());
    }
    return false;
  }

  void report_failure(const Lease& l, const std::string& pfx, const std::string& error) {
    count(&WorkerStats::tiles_failed);
    // The report carries the last lines logged about this lease (their prefix is `pfx: `), bounded in count and size.
    const protocol::FailReport report{error, recent_.log().lines_with(pfx + ":", kFailureLogLines, kFailureLogLineBytes)};
    if (post_lease_message(pfx, "fail", routes::lease_fail(l.id), report, 10)) spdlog::info("{}: failure reported", pfx);
  }

  void release(const Lease& l, const std::string& pfx) {
    count(&WorkerStats::tiles_released);
    if (post_lease_message(pfx, "release", routes::lease_release(l.id), json::object(), 3)) spdlog::info("{}: tile handed back", pfx);
  }

  RecentLogScope recent_;  // first: it sees everything the worker logs
  const WorkerOptions& opt_;
  const std::atomic<int>& stop_;
  client::HttpUrl url_;
  client::HttpClient http_;
  client::HttpClient heartbeat_http_;  // used only by the heartbeat thread
  client::HttpClient upload_http_;     // used only by the upload thread
  JobScenes scenes_;  // looked up by the companion's thread too (head_start, lease_request_body)
  client::Backoff idle_, retry_;
  std::string name_, id_;
  std::string secret_;  // from the registration: sent with every request that acts as this worker
  int threads_ = 1;
  tbb::task_arena arena_;  // every render runs in it, begun-ahead ones included (threads_ threads)
  std::optional<ArenaPinning> pinning_;  // with opt.cpus: each of arena_'s threads on its own CPU
  std::chrono::milliseconds heartbeat_period_{5000};
  std::chrono::milliseconds lease_length_{30'000};  // from the registration
  mutable std::atomic<std::chrono::steady_clock::time_point> stop_seen_{};  // see stopping()
  bool down_ = false;
  std::atomic<double> lease_rtt_ms_{0};  // moving average of lease round trips (0: none yet)
  // The next lease asked for with the last upload (valid until taken), and the worker id it was asked for as.
  std::future<std::optional<PrefetchedLease>> upload_lease_;
  std::string upload_lease_worker_;
  std::mutex stats_mutex_;
  WorkerStats stats_;    // guarded by stats_mutex_
  UploadQueue uploads_;  // last: destroyed first, after the upload in flight has finished
};

}  // namespace

WorkerStats run_worker(const WorkerOptions& options, const std::atomic<int>& stop_requests) {
  std::unique_ptr<tbb::global_control> limit;
  if (options.threads > 0)
    limit = std::make_unique<tbb::global_control>(tbb::global_control::max_allowed_parallelism, size_t(options.threads));
  Worker worker(options, stop_requests);
  return worker.run();
}

}  // namespace tessera::worker
