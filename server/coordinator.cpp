#include "server/coordinator.h"

#include "server/database.h"
#include "server/http_server.h"
#include "server/monitor_handler.h"
#include "server/result_thread.h"

#include <boost/asio/io_context.hpp>
#include <boost/asio/post.hpp>
#include <boost/asio/signal_set.hpp>
#include <boost/asio/steady_timer.hpp>
#include <boost/asio/thread_pool.hpp>
#include <spdlog/spdlog.h>

#include <atomic>
#include <cctype>
#include <csignal>
#include <pthread.h>
#include <signal.h>
#include <thread>

namespace tessera::server {

namespace asio = boost::asio;

void set_listen_address(CoordinatorOptions& o, const std::string& text) {
  const auto number = [&text](const std::string& digits, int max, const char* what) {
    int n = -1;
    try {
      size_t used = 0;
      n = std::stoi(digits, &used);
      if (used != digits.size() || !std::isdigit(static_cast<unsigned char>(digits.front()))) n = -1;
    } catch (const std::exception&) {
      n = -1;
    }
    if (n < 0 || n > max) throw std::invalid_argument("listen address '" + text + "' is not " + what);
    return n;
  };
  if (text.rfind("fd:", 0) == 0) {
    o.listen_fd = number(text.substr(3), 1 << 20, "fd:N with a descriptor number N");
    return;
  }
  const size_t colon = text.rfind(':');
  std::string host = colon == std::string::npos ? "" : text.substr(0, colon);
  const std::string port_text = colon == std::string::npos ? text : text.substr(colon + 1);
  if (host.size() >= 2 && host.front() == '[' && host.back() == ']') host = host.substr(1, host.size() - 2);
  if (host.empty() || host == "localhost") host = "127.0.0.1";
  o.port = static_cast<unsigned short>(number(port_text, 65535, "HOST:PORT with a port in 0..65535"));
  o.host = host;
  o.listen_fd = -1;
}

namespace {

int64_t wall_ms() {
  return std::chrono::duration_cast<std::chrono::milliseconds>(std::chrono::system_clock::now().time_since_epoch()).count();
}

// Without both tokens anyone who can connect could submit jobs or pose as a worker, so only loopback is allowed.
void check_access_setup(const std::string& host, const AccessTokens& tokens) {
  for (const auto& [token, what] : {std::pair{&tokens.client, "client"}, std::pair{&tokens.worker, "worker"}}) {
    if (token->empty()) continue;
    if (const std::string problem = token_problem(*token); !problem.empty())
      throw std::runtime_error(std::string("the ") + what + " token is not usable: " + problem);
  }
  if (!tokens.client.empty() && constant_time_equal(tokens.client, tokens.worker))
    throw std::runtime_error("the client and worker tokens must differ (a worker could otherwise submit and cancel jobs)");
  boost::system::error_code ec;
  const auto addr = asio::ip::make_address(host, ec);
  if (ec) throw std::runtime_error("cannot listen on '" + host + "': not an IP address");
  if (!addr.is_loopback() && !Credentials(tokens).complete())
    throw std::runtime_error("refusing to listen on " + host +
                             " without access tokens for clients and workers: set --client-token-file (or --users) and "
                             "--worker-token-file (or a user with the worker role), or TESSERA_CLIENT_TOKEN and "
                             "TESSERA_WORKER_TOKEN, or listen on 127.0.0.1");
}

// The scheduler's tunables from the coordinator's options.
SchedulerConfig scheduler_config(const CoordinatorOptions& o) {
  SchedulerConfig c;
  c.lease_ms = int64_t(o.lease_seconds * 1000.0);
  c.tile_failure_workers = o.tile_failure_workers;
  c.worker_failure_limit = o.worker_failure_limit;
  c.id_tag = random_hex(3);
  c.max_workers = o.max_workers;
  c.job_tile_log_bytes = o.job_tile_log_bytes;
  c.worker_retention_ms = int64_t(o.worker_retention_seconds * 1000.0);
  c.webhooks = o.webhooks;
  return c;
}

// The API's options with what the coordinator's webhook settings give it: the addresses submissions may name and the
// delivery log (the store's, when it keeps one).
ApiOptions api_options(const CoordinatorOptions& o, CoordinatorStore& store) {
  ApiOptions a = o.limits;
  a.notify_allowed = WebhookAllowList(o.webhook_allow);
  a.webhook_log = dynamic_cast<WebhookLog*>(&store);
  return a;
}

// Webhook addresses are checked before anything opens; a coordinator without an outbox (in memory) refuses them.
void check_webhook_setup(const CoordinatorOptions& o) {
  for (const std::string& url : o.webhooks) parse_webhook_url(url);
  for (const std::string& url : o.webhook_allow) parse_webhook_url(url);
  if ((!o.webhooks.empty() || !o.webhook_allow.empty()) && o.durability == Durability::none)
    throw std::runtime_error("webhooks need the outbox of the data folder's database: not with --durability none");
}

}  // namespace

struct Coordinator::Impl {
  explicit Impl(CoordinatorOptions o)
      : opt(std::move(o)),
        disk(opt.data_dir, opt.min_free_disk),
        blobs(blobs_dir(opt.data_dir), opt.durability),
        store(open_coordinator_store(opt.data_dir, opt.durability)),
        sched(scheduler_config(opt), wall_ms, *store),
        bus(opt.events, random_hex(4)),
        farm_events(bus),
        api(sched, blobs, *store, metrics, wall_ms, api_options(opt, *store), bus, farm_events, disk,
            // on the handler pool: the next lease an upload asked for; on the results' thread: a finished job's result
            [this](std::function<void()> work) { asio::post(pool, std::move(work)); },
            [this](std::function<void()> work) { results.post(std::move(work)); }),
        monitor(api, !opt.limits.tokens.client.empty() || !opt.limits.tokens.users_file.empty()),
        pool(std::size_t(opt.handler_threads > 0 ? opt.handler_threads : std::max(2u, std::thread::hardware_concurrency()))),
        admission(monitor, opt.admission),
        server(ioc, pool, admission,
               HttpServerOptions{opt.host, opt.port, opt.listen_fd, opt.read_timeout, opt.header_limit, opt.max_connections,
                                 opt.stream_idle, opt.peers, opt.tls}),
        tick(ioc),
        signals(ioc) {
    if (WebhookLog* log = dynamic_cast<WebhookLog*>(store.get()); log && (!opt.webhooks.empty() || !opt.webhook_allow.empty()))
      sender = std::make_unique<WebhookSender>(*log, opt.webhook_sender, wall_ms);
  }

  void arm_tick() {
    tick.expires_after(std::chrono::seconds(1));
    tick.async_wait([this](boost::system::error_code ec) {
      if (ec || stopped) return;
      const uint64_t expiries = sched.counters().lease_expiries;  // counters() reclaims expired leases
      if (expiries > last_expiries) spdlog::warn("{} lease(s) expired; their tiles are pending again", expiries - last_expiries);
      last_expiries = expiries;
      farm_events.workers_checked(sched.workers());  // workers lost (offline) or back since the last tick
      if (++ticks % kSweepTicks == 0) asio::post(pool, [this] { sweep(); });  // deletes files: not on the network thread
      if (disk.full() && !recovering.exchange(true)) asio::post(pool, [this] { recover_disk(); });
      arm_tick();
    });
  }

  // While the disk is full, once a second: the database's log is checkpointed and cut (the room it needs first),
  // then the changes that waited are stored and the results that did not fit are written. The spell ends when these
  // succeed with at least kResumeBytes free; a write that fails for want of space leaves it for the next second.
  void recover_disk() {
    try {
      if (store->make_room() && disk.free_bytes() >= kResumeBytes) {
        sched.store_pending();
        if (api.write_waiting_results()) disk.note_room();
      }
    } catch (const std::exception& e) {
      if (!is_disk_full(e)) spdlog::error("after the disk was full: {}", e.what());
    }
    recovering = false;
  }

  void sweep() {
    try {
      api.sweep();
    } catch (const std::exception& e) {
      spdlog::error("retention sweep: {}", e.what());  // tried again at the next sweep
    }
  }

  static constexpr uint64_t kSweepTicks = 60;  // retention and blob collection run once a minute
  static constexpr uint64_t kResumeBytes = uint64_t(1) << 20;  // free space that ends a full disk's spell
  CoordinatorOptions opt;
  DiskSpace disk;  // the data folder's free space; full from a write that found no room until one succeeds again
  DiskBlobStore blobs;
  std::unique_ptr<CoordinatorStore> store;  // jobs, tiles, leases, workers and job records (DIR/tessera.db or memory)
  Scheduler sched;
  EventBus bus;             // GET /v1/events
  FarmEvents farm_events;   // what handlers and the tick publish to the bus
  Metrics metrics;
  Api api;
  MonitorHandler monitor;  // the web monitor at /, in front of the API
  asio::io_context ioc;
  ResultThread results;  // finished jobs' results (destroyed after the pool, whose work may queue one)
  asio::thread_pool pool;
  AdmissionHandler admission;  // submissions on their own pool, in front of the monitor (after ioc: its tasks hold ioc work)
  HttpServer server;
  asio::steady_timer tick;
  asio::signal_set signals;
  std::atomic<bool> stopped{false};
  std::atomic<bool> recovering{false};  // a recover_disk() is queued or running
  uint64_t last_expiries = 0;
  uint64_t ticks = 0;
  std::unique_ptr<WebhookSender> sender;  // delivers the outbox (last: stopped before the store closes)
};

Coordinator::Coordinator(CoordinatorOptions options) {
  if (options.data_dir.empty()) throw std::runtime_error("the coordinator needs a data folder (--data)");
  if (options.lease_seconds <= 0) throw std::runtime_error("--lease-seconds must be positive");
  if (options.listen_fd >= 0) options.host = listening_address(options.listen_fd);  // the rules are the address's
  check_access_setup(options.host, options.limits.tokens);
  try {
    check_webhook_setup(options);
  } catch (const std::invalid_argument& e) {
    throw std::runtime_error(e.what());
  }
  try {
    impl_ = std::make_unique<Impl>(std::move(options));
  } catch (const StorageError& e) {
    throw std::runtime_error(std::string("cannot open the coordinator's state: ") + e.what());
  }
  if (const size_t n = impl_->blobs.leftovers_removed() + impl_->store->leftovers_removed(); n > 0)
    spdlog::info("removed {} temporary file(s) left by an interrupted run", n);
  SchedulerCounters c = impl_->sched.counters();
  if (c.jobs[JobState::queued] + c.jobs[JobState::running] > 0)
    spdlog::info("resuming {} queued and {} running job(s) with {} live lease(s) from {}", c.jobs[JobState::queued],
                 c.jobs[JobState::running], c.active_leases, impl_->store->where());
  impl_->api.recover();
  if (impl_->opt.handle_signals) {
    // Caught from here on, before the caller announces readiness: a signal that arrives before run() is held by the
    // signal set and acted on once run() starts, instead of killing the process with the default action.
    impl_->signals.add(SIGINT);
    impl_->signals.add(SIGTERM);
    if (impl_->server.tls() || !impl_->opt.limits.tokens.users_file.empty()) impl_->signals.add(SIGHUP);
    wait_for_signal();
  }
}

Coordinator::~Coordinator() {
  if (impl_) {
    impl_->pool.stop();
    impl_->pool.join();
    impl_->results.join();
  }
}

boost::asio::ip::tcp::endpoint Coordinator::endpoint() const { return impl_->server.endpoint(); }

void Coordinator::run() {
  Impl& m = *impl_;
  m.server.start();
  m.arm_tick();
  auto serve = [&m] {
    for (;;) {
      try {
        m.ioc.run();
        return;
      } catch (const std::exception& e) {
        spdlog::error("network thread: {}", e.what());
      } catch (...) {
        spdlog::error("network thread: unknown exception");
      }
    }
  };
  std::vector<std::thread> extra;
  for (int i = 1; i < m.opt.io_threads; ++i) extra.emplace_back(serve);
  serve();
  for (auto& t : extra) t.join();
  m.pool.join();
  m.results.join();
  m.admission.join();
  if (m.opt.handle_signals) {
    // A supervisor often signals twice (Slurm's scancel reaches both the batch shell, which passes SIGTERM on, and
    // this process). Destroying the signal_set restores the default action, so a late SIGTERM would kill the
    // process while it closes its database. Only this thread is left, so blocking here defers any such signal to
    // exit, where it is discarded: the stop already under way is the one that counts.
    sigset_t stop_signals;
    sigemptyset(&stop_signals);
    sigaddset(&stop_signals, SIGINT);
    sigaddset(&stop_signals, SIGTERM);
    pthread_sigmask(SIG_BLOCK, &stop_signals, nullptr);
  }
  spdlog::info("coordinator stopped");
}

void Coordinator::wait_for_signal() {
  impl_->signals.async_wait([this](boost::system::error_code ec, int sig) {
    if (ec) return;
    if (sig == SIGHUP) {
      if (impl_->server.tls()) {
        try {
          impl_->server.reload_tls();
          spdlog::info("received SIGHUP: TLS certificate and key re-read; new connections use them");
        } catch (const std::exception& e) {
          spdlog::error("received SIGHUP: {}; still serving with the previous certificate", e.what());
        }
      }
      if (!impl_->opt.limits.tokens.users_file.empty()) {
        try {
          const size_t n = impl_->api.reload_users();
          spdlog::info("received SIGHUP: users file {} re-read: {} user(s)", impl_->opt.limits.tokens.users_file.string(), n);
        } catch (const std::exception& e) {
          spdlog::error("received SIGHUP: {}; still serving with the users it had", e.what());
        }
      }
      return wait_for_signal();
    }
    spdlog::info("received signal {}: no new connections; finishing requests in flight", sig);
    stop();
  });
}

void Coordinator::stop() {
  Impl& m = *impl_;
  asio::post(m.ioc, [&m] {
    if (m.stopped.exchange(true)) return;
    m.api.stop_holding_leases();  // held lease requests are answered, so none keeps the shutdown waiting
    m.server.shutdown();
    m.bus.close();  // every event stream ends
    m.tick.cancel();
    boost::system::error_code ec;
    m.signals.cancel(ec);
  });
}

}  // namespace tessera::server
