// libFuzzer target: raw bytes as one or more HTTP/1.1 requests, parsed by Beast's request parser (with the
// transport's header limit and the API's body limits) and answered by Api::handle over a coordinator state in a
// private temporary folder. State carries over between requests and inputs (ids are predictable: "j-fz-1",
// "w-fz-1", "l-fz-1"), so registering, leasing and uploading can chain. Findings: crashes, UB, leaks, and any
// error response (>= 400) whose body is not `{"error": "..."}`.
#include "server/api.h"
#include "server/database.h"
#include "server/disk_space.h"

#include <boost/beast/core/flat_buffer.hpp>
#include <boost/beast/http.hpp>
#include <nlohmann/json.hpp>
#include <spdlog/spdlog.h>

#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <filesystem>
#include <unistd.h>

namespace fs = std::filesystem;
namespace http = boost::beast::http;
using namespace tessera::server;

namespace {

// A coordinator without transport, over a fresh data folder removed at exit.
struct State {
  fs::path dir = fs::temp_directory_path() / ("tessera-fuzz-http-" + std::to_string(::getpid()));
  int64_t now = 1'000'000;  // a clock that advances 1 s per request, so leases expire now and then
  DiskBlobStore blobs{dir / "blobs"};
  DurableStore store{dir};  // as the coordinator wires it: scheduler state and job records in SQLite
  Scheduler sched{SchedulerConfig{30'000, 3, 2, "fz"}, [this] { return now; }, store};
  Metrics metrics;
  EventBus bus{EventBusOptions{}, "fz"};
  FarmEvents events{bus};
  DiskSpace disk{dir, 0};  // no free-space floor: the fuzzer's inputs, not the machine's disk, decide the answers
  Api api{sched, blobs, store, metrics, [this] { return now; }, options(), bus, events, disk};

  static ApiOptions options() {
    ApiOptions o;
    o.json_limit = 64 * 1024;
    o.blob_limit = 256 * 1024;
    o.result_limit = 256 * 1024;
    o.max_queued_jobs = 8;
    o.max_job_pixels = 64 * 64;
    o.max_job_samples = 1e6;
    return o;
  }
  ~State() {
    std::error_code ec;
    fs::remove_all(dir, ec);
  }
};

// Error responses must carry a JSON object with an "error" string.
void check_response(bool head, const HttpResponse& res) {
  if (res.result_int() < 400 || head) return;
  const auto j = nlohmann::json::parse(res.body(), nullptr, false);
  if (!j.is_object() || !j.contains("error") || !j["error"].is_string()) {
    spdlog::critical("error response {} without a JSON error body: '{}'", res.result_int(), res.body());
    std::abort();
  }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  static State* st = [] {
    spdlog::set_level(spdlog::level::off);
    static State s;
    return &s;
  }();
  boost::beast::flat_buffer buffer;
  buffer.commit(boost::asio::buffer_copy(buffer.prepare(size), boost::asio::buffer(data, size)));
  for (int requests = 0; requests < 8 && buffer.size() > 0; ++requests) {
    http::request_parser<http::string_body> parser;
    parser.header_limit(8 * 1024);
    parser.eager(false);
    boost::beast::error_code ec;
    // Header first, then the body under the limit the API picks for this header (as the transport does).
    while (!parser.is_header_done()) {
      const std::size_t used = parser.put(buffer.data(), ec);
      buffer.consume(used);
      if (ec || used == 0) return 0;
    }
    parser.body_limit(st->api.body_limit(parser.get().base()));
    parser.eager(true);
    while (!parser.is_done()) {
      const std::size_t used = parser.put(buffer.data(), ec);
      buffer.consume(used);
      if (ec == http::error::need_more) {
        parser.put_eof(ec);  // the input ended: a body without its length is complete now, others are truncated
        if (ec || !parser.is_done()) return 0;
        break;
      }
      if (ec || used == 0) return 0;
    }
    HttpRequest req = parser.release();
    const bool head = req.method() == http::verb::head;
    st->now += 1000;
    const HttpResponse res = st->api.handle(std::move(req));
    check_response(head, res);
  }
  return 0;
}
