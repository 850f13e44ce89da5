// Load generator for the coordinator's status endpoints: C keep-alive connections, each on its own thread, send GETs
// round-robin over the given targets for T seconds; prints requests per second and latency percentiles per target.
// Usage: load_client --url http://127.0.0.1:8470 --connections 16 --seconds 10 [--token-file F] TARGET...
#include "client/http_client.h"

#include <CLI/CLI.hpp>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstdio>
#include <fstream>
#include <map>
#include <string>
#include <thread>
#include <vector>

namespace {

using Clock = std::chrono::steady_clock;

// What one connection measured.
struct ConnectionLog {
  std::vector<std::vector<double>> latency_ms;  // per target
  std::vector<int64_t> errors;                  // per target: transport errors and non-2xx answers
};

double percentile(std::vector<double>& v, double p) {
  if (v.empty()) return 0.0;
  const size_t k = std::min(v.size() - 1, size_t(p * double(v.size())));
  std::nth_element(v.begin(), v.begin() + std::ptrdiff_t(k), v.end());
  return v[k];
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"Load generator for the Tessera coordinator's status endpoints"};
  std::string url = "http://127.0.0.1:8470", token_file;
  int connections = 16;
  double seconds = 10;
  std::vector<std::string> targets;
  app.add_option("--url", url, "Coordinator URL")->capture_default_str();
  app.add_option("--connections", connections, "Concurrent keep-alive connections")->check(CLI::Range(1, 4096))->capture_default_str();
  app.add_option("--seconds", seconds, "Duration")->check(CLI::Range(0.1, 3600.0))->capture_default_str();
  app.add_option("--token-file", token_file, "File holding a bearer token to send");
  app.add_option("targets", targets, "Request targets, e.g. /healthz /v1/jobs/ID")->required();
  CLI11_PARSE(app, argc, argv);

  std::string token;
  if (!token_file.empty()) {
    std::ifstream in(token_file);
    std::getline(in, token);
  }
  const tessera::client::HttpUrl parsed = tessera::client::parse_http_url(url);
  std::vector<ConnectionLog> logs(static_cast<size_t>(connections));
  std::atomic<bool> stop{false};
  std::vector<std::thread> threads;
  const auto t0 = Clock::now();
  for (int c = 0; c < connections; ++c) {
    threads.emplace_back([&, c] {
      ConnectionLog& log = logs[size_t(c)];
      log.latency_ms.resize(targets.size());
      log.errors.assign(targets.size(), 0);
      tessera::client::HttpClient http(parsed);
      http.set_bearer_token(token);
      for (size_t i = size_t(c) % targets.size(); !stop.load(std::memory_order_relaxed); i = (i + 1) % targets.size()) {
        const auto a = Clock::now();
        try {
          const auto r = http.send("GET", targets[i]);
          if (r.status < 200 || r.status >= 300) ++log.errors[i];
        } catch (const std::exception&) {
          ++log.errors[i];
        }
        log.latency_ms[i].push_back(std::chrono::duration<double, std::milli>(Clock::now() - a).count());
      }
    });
  }
  std::this_thread::sleep_for(std::chrono::duration<double>(seconds));
  stop = true;
  for (auto& t : threads) t.join();
  const double elapsed = std::chrono::duration<double>(Clock::now() - t0).count();

  std::printf("%d connections, %.1f s\n", connections, elapsed);
  std::printf("  %-28s %10s %9s %9s %9s %9s %7s\n", "target", "requests", "req/s", "p50 ms", "p99 ms", "max ms", "errors");
  std::vector<double> all;
  int64_t all_errors = 0;
  for (size_t i = 0; i < targets.size(); ++i) {
    std::vector<double> v;
    int64_t errors = 0;
    for (auto& log : logs) {
      v.insert(v.end(), log.latency_ms[i].begin(), log.latency_ms[i].end());
      errors += log.errors[i];
    }
    all.insert(all.end(), v.begin(), v.end());
    all_errors += errors;
    const double n = double(v.size());
    const double mx = v.empty() ? 0.0 : *std::max_element(v.begin(), v.end());
    const double p50 = percentile(v, 0.50), p99 = percentile(v, 0.99);
    std::string label = targets[i].size() > 28 ? targets[i].substr(0, 25) + "..." : targets[i];
    std::printf("  %-28s %10.0f %9.0f %9.2f %9.2f %9.2f %7lld\n", label.c_str(), n, n / elapsed, p50, p99, mx,
                static_cast<long long>(errors));
  }
  const double n = double(all.size());
  const double p50 = percentile(all, 0.50), p99 = percentile(all, 0.99);
  std::printf("  %-28s %10.0f %9.0f %9.2f %9.2f %9s %7lld\n", "all", n, n / elapsed, p50, p99, "",
              static_cast<long long>(all_errors));
  return all_errors == 0 ? 0 : 1;
}
