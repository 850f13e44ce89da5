#include "server/coordinator.h"

#include "server/http_server.h"

#include <boost/asio/io_context.hpp>
#include <boost/asio/post.hpp>
#include <boost/asio/signal_set.hpp>
#include <boost/asio/steady_timer.hpp>
#include <boost/asio/thread_pool.hpp>
#include <spdlog/spdlog.h>

#include <atomic>
#include <csignal>
#include <thread>

namespace tessera::server {

namespace asio = boost::asio;

std::pair<std::string, unsigned short> parse_listen_address(const std::string& text) {
  const size_t colon = text.rfind(':');
  std::string host = colon == std::string::npos ? "" : text.substr(0, colon);
  const std::string port_text = colon == std::string::npos ? text : text.substr(colon + 1);
  if (host.size() >= 2 && host.front() == '[' && host.back() == ']') host = host.substr(1, host.size() - 2);
  if (host.empty() || host == "localhost") host = "127.0.0.1";
  int port = -1;
  try {
    size_t used = 0;
    port = std::stoi(port_text, &used);
    if (used != port_text.size()) port = -1;
  } catch (const std::exception&) {
    port = -1;
  }
  if (port < 0 || port > 65535) throw std::invalid_argument("listen address '" + text + "' is not HOST:PORT with a port in 0..65535");
  return {host, static_cast<unsigned short>(port)};
}

namespace {

int64_t wall_ms() {
  return std::chrono::duration_cast<std::chrono::milliseconds>(std::chrono::system_clock::now().time_since_epoch()).count();
}

void require_loopback(const std::string& host) {
  boost::system::error_code ec;
  const auto addr = asio::ip::make_address(host, ec);
  if (ec) throw std::runtime_error("cannot listen on '" + host + "': not an IP address");
  if (!addr.is_loopback())
    throw std::runtime_error("refusing to listen on " + host +
                             ": access tokens are not implemented yet, so the coordinator only listens on loopback");
}

}  // namespace

struct Coordinator::Impl {
  explicit Impl(CoordinatorOptions o)
      : opt(std::move(o)),
        blobs(opt.data_dir / "blobs"),
        jobs(opt.data_dir / "jobs", opt.data_dir / "tmp"),
        sched(SchedulerConfig{int64_t(opt.lease_seconds * 1000.0), 3, 2, random_hex(3)}, wall_ms),
        api(sched, blobs, jobs, metrics, wall_ms, with_heartbeat(opt)),
        pool(std::size_t(opt.handler_threads > 0 ? opt.handler_threads : std::max(2u, std::thread::hardware_concurrency()))),
        server(ioc, pool, api, HttpServerOptions{opt.host, opt.port, opt.read_timeout, opt.header_limit, opt.max_connections}),
        tick(ioc),
        signals(ioc) {}

  static ApiOptions with_heartbeat(const CoordinatorOptions& o) {
    ApiOptions a = o.limits;
    a.heartbeat_seconds = o.heartbeat_seconds;
    return a;
  }

  void arm_tick() {
    tick.expires_after(std::chrono::seconds(1));
    tick.async_wait([this](boost::system::error_code ec) {
      if (ec || stopped) return;
      const uint64_t expiries = sched.counters().lease_expiries;  // counters() reclaims expired leases
      if (expiries > last_expiries) spdlog::warn("{} lease(s) expired; their tiles are pending again", expiries - last_expiries);
      last_expiries = expiries;
      arm_tick();
    });
  }

  CoordinatorOptions opt;
  DiskBlobStore blobs;
  DiskJobStore jobs;
  Scheduler sched;
  Metrics metrics;
  Api api;
  asio::io_context ioc;
  asio::thread_pool pool;
  HttpServer server;
  asio::steady_timer tick;
  asio::signal_set signals;
  std::atomic<bool> stopped{false};
  uint64_t last_expiries = 0;
};

Coordinator::Coordinator(CoordinatorOptions options) {
  if (options.data_dir.empty()) throw std::runtime_error("the coordinator needs a data folder (--data)");
  if (options.lease_seconds <= 0) throw std::runtime_error("--lease-seconds must be positive");
  require_loopback(options.host);
  impl_ = std::make_unique<Impl>(std::move(options));
}

Coordinator::~Coordinator() {
  if (impl_) {
    impl_->pool.stop();
    impl_->pool.join();
  }
}

boost::asio::ip::tcp::endpoint Coordinator::endpoint() const { return impl_->server.endpoint(); }

void Coordinator::run() {
  Impl& m = *impl_;
  m.server.start();
  m.arm_tick();
  if (m.opt.handle_signals) {
    m.signals.add(SIGINT);
    m.signals.add(SIGTERM);
    m.signals.async_wait([this](boost::system::error_code ec, int sig) {
      if (ec) return;
      spdlog::info("received signal {}: no new connections; finishing requests in flight", sig);
      stop();
    });
  }
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
  spdlog::info("coordinator stopped");
}

void Coordinator::stop() {
  Impl& m = *impl_;
  asio::post(m.ioc, [&m] {
    if (m.stopped.exchange(true)) return;
    m.server.shutdown();
    m.tick.cancel();
    boost::system::error_code ec;
    m.signals.cancel(ec);
  });
}

}  // namespace tessera::server
