// The coordinator process: storage, scheduler, API and HTTP transport wired together, with graceful shutdown.
#pragma once

#include "server/admission_handler.h"
#include "server/api.h"
#include "server/event_bus.h"
#include "server/tls_context.h"
#include "server/webhook_sender.h"

#include <boost/asio/ip/tcp.hpp>

#include <chrono>
#include <cstddef>
#include <filesystem>
#include <memory>
#include <string>

namespace tessera::server {

/// Everything `tessera serve` can be told.
struct CoordinatorOptions {
  std::string host = "127.0.0.1";              ///< Address to bind (beyond loopback only with both tokens set).
  unsigned short port = 8470;                  ///< Port (0: an ephemeral one).
  int listen_fd = -1;  ///< A listening TCP socket to serve on instead of binding host:port (inherited; same rules).
  std::filesystem::path data_dir;              ///< Holds tessera.db, blobs/, jobs/ and tmp/.
  Durability durability = Durability::machine;  ///< What acknowledged state survives (process: no disk flushes; none: kept in memory).
  /// Free bytes on data_dir's file system below which submissions and blob uploads are refused with 507 (0: only
  /// when the disk is full), so that admitted jobs keep room to finish.
  uint64_t min_free_disk = uint64_t(64) << 20;
  double lease_seconds = protocol::kDefaultLeaseSeconds;  ///< Lease length.
  int worker_failure_limit = SchedulerConfig{}.worker_failure_limit;  ///< Failures blocklisting a worker for a job.
  int tile_failure_workers = SchedulerConfig{}.tile_failure_workers;  ///< Workers failing one tile that fail its job.
  int64_t max_workers = SchedulerConfig{}.max_workers;  ///< Registered workers at most (more registrations get 503).
  int64_t job_tile_log_bytes = SchedulerConfig{}.job_tile_log_bytes;  ///< Bytes of done tiles' logs kept per job.
  /// An offline worker holding no lease is forgotten this long after it was last seen.
  double worker_retention_seconds = double(SchedulerConfig{}.worker_retention_ms) / 1000.0;
  ApiOptions limits;  ///< Heartbeat interval, body sizes, queued jobs, job size, access tokens, retention, registrations.
  std::chrono::milliseconds read_timeout = HttpServerOptions{}.read_timeout;  ///< Whole-request read timeout.
  std::size_t header_limit = HttpServerOptions{}.header_limit;        ///< Largest request header.
  std::size_t max_connections = HttpServerOptions{}.max_connections;  ///< Open connections (more get 503).
  PeerLimitOptions peers;                      ///< Limits on peers before they show a credential.
  EventBusOptions events;                      ///< GET /v1/events: open streams (more get 503), queues, resume ring.
  /// An event stream writes a keep-alive comment after this long quiet.
  std::chrono::milliseconds stream_idle = HttpServerOptions{}.stream_idle;
  TlsServerFiles tls;                          ///< HTTPS certificate files (none: plain HTTP).
  int io_threads = 1;                          ///< Network threads.
  int handler_threads = 0;                     ///< Request handler threads (0: max(2, cores)).
  AdmissionOptions admission;                  ///< Job submissions checked at once and waiting (their own pool).
  bool handle_signals = false;                 ///< Stop gracefully on SIGINT/SIGTERM; re-read the TLS files on SIGHUP.
  std::vector<std::string> webhooks;           ///< Webhook addresses told of every job's end.
  std::vector<std::string> webhook_allow;      ///< The addresses a submission's own webhook ("notify") may name.
  WebhookSenderOptions webhook_sender;         ///< Signing secret, attempts, backoff and timeout of deliveries.
};

/// A running coordinator. Construction binds the port; run() serves until stop() (or a signal).
class Coordinator {
 public:
  /// Opens the stores under data_dir and binds; throws std::runtime_error with context on failure.
  explicit Coordinator(CoordinatorOptions options);
  ~Coordinator();
  Coordinator(const Coordinator&) = delete;
  Coordinator& operator=(const Coordinator&) = delete;

  /// The bound address.
  boost::asio::ip::tcp::endpoint endpoint() const;
  /// Serves on this thread (plus io_threads - 1 more) until stopped; in-flight requests finish first.
  void run();
  /// Asks run() to stop gracefully; callable from any thread, more than once.
  void stop();

 private:
  void wait_for_signal();  // SIGINT/SIGTERM stop, SIGHUP reloads TLS and waits again
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

/// Sets where `o` listens from `serve --listen`'s text: "HOST:PORT" (or ":PORT", or "PORT") sets host and port, "fd:N"
/// sets listen_fd (a listening socket inherited as descriptor N); throws std::invalid_argument naming the text.
void set_listen_address(CoordinatorOptions& o, const std::string& text);

}  // namespace tessera::server
