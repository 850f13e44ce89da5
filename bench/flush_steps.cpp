// A large file flushed to the disk beside a small file flushed often, as the coordinator flushes a finished job's
// result (50 MiB for 2048x2048 float RGB) while its group commit flushes the log that acknowledges uploads: the small
// flushes' latency and the large flush's time, with one fsync of the whole file against flush_to_disk's steps
// (core/util/file_io.h), alternating rounds. The files live in DIR (default: the system's temp folder; it must be on
// the disk to mean anything, not tmpfs).
//   ./build/bench/flush_steps [ROUNDS] [DIR]      (ROUNDS = 8)
#include "bench/run_environment.h"
#include "core/util/file_io.h"

#include <fcntl.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <mutex>
#include <random>
#include <string>
#include <thread>
#include <vector>

using namespace tessera;
namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;

namespace {

double ms_since(Clock::time_point t0) { return std::chrono::duration<double, std::milli>(Clock::now() - t0).count(); }

double percentile(std::vector<double> v, double p) {
  if (v.empty()) return 0.0;
  std::sort(v.begin(), v.end());
  return v[std::min(v.size() - 1, size_t(p * double(v.size())))];
}

struct Variant {
  const char* name;
  bool steps;
  std::vector<double> big_ms;    // the large file's flush, per round
  std::vector<double> small_ms;  // the small flushes that overlapped it
};

}  // namespace

int main(int argc, char** argv) {
  const int rounds = argc > 1 ? std::max(1, std::atoi(argv[1])) : 8;
  const fs::path dir = argc > 2 ? fs::path(argv[2]) : fs::temp_directory_path();
  const fs::path big_path = dir / ("tessera_flush_big_" + std::to_string(::getpid()));
  const fs::path log_path = dir / ("tessera_flush_log_" + std::to_string(::getpid()));

  std::string big(size_t(50) << 20, '\0');  // incompressible, in case the file system compresses
  std::mt19937_64 rng(1);
  for (size_t i = 0; i + 8 <= big.size(); i += 8) {
    const uint64_t r = rng();
    std::copy_n(reinterpret_cast<const char*>(&r), 8, big.data() + i);
  }

  // The small flushes: 8 KiB appended and fdatasync'ed every 2 ms, each latency recorded with whether the large
  // flush was under way when it started.
  std::atomic<bool> stop{false};
  std::atomic<int> flushing{-1};  // the variant whose large flush is under way, -1 for none
  std::mutex mu;
  std::vector<Variant> variants = {{"one fsync", false, {}, {}}, {"flush_to_disk", true, {}, {}}};
  std::thread logger([&] {
    const int fd = ::open(log_path.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
    if (fd < 0) {
      std::perror("flush_steps: log file");
      std::exit(1);
    }
    const std::string block(8192, 'l');
    while (!stop) {
      if (write_all(fd, block) != 0) std::exit(1);
      const int during = flushing.load();
      const Clock::time_point t0 = Clock::now();
      ::fdatasync(fd);
      const double ms = ms_since(t0);
      if (during >= 0) {
        std::lock_guard lock(mu);
        variants[size_t(during)].small_ms.push_back(ms);
      }
      std::this_thread::sleep_for(std::chrono::milliseconds(2));
    }
    ::close(fd);
  });

  for (int r = 0; r < rounds; ++r) {
    for (int v = 0; v < 2; ++v) {
      const int fd = ::open(big_path.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
      if (fd < 0 || write_all(fd, big) != 0) {
        std::perror("flush_steps: large file");
        return 1;
      }
      std::this_thread::sleep_for(std::chrono::milliseconds(100));  // the log's flushes settle
      flushing = v;
      const Clock::time_point t0 = Clock::now();
      const int err = variants[size_t(v)].steps ? flush_to_disk(fd) : (::fsync(fd) == 0 ? 0 : errno);
      const double ms = ms_since(t0);
      flushing = -1;
      ::close(fd);
      if (err != 0) {
        std::fprintf(stderr, "flush_steps: cannot flush %s: errno %d\n", big_path.c_str(), err);
        return 1;
      }
      variants[size_t(v)].big_ms.push_back(ms);
      std::this_thread::sleep_for(std::chrono::milliseconds(100));
    }
  }
  stop = true;
  logger.join();
  fs::remove(big_path);
  fs::remove(log_path);

  std::printf("flush_steps: commit %s\n",
              bench::commit_description(TESSERA_SOURCE_DIR, TESSERA_CONFIGURE_COMMIT).c_str());
  std::printf("machine: %s, nproc %u; load average at the end %s\n", bench::cpu_model().c_str(),
              std::thread::hardware_concurrency(), bench::load_average().c_str());
  std::printf("command: ./build/bench/flush_steps %d %s (file system: %s); %d alternating rounds\n", rounds,
              dir.c_str(), bench::first_line_of("stat -f -c %T '" + dir.string() + "'").c_str(), rounds);
  std::printf("a 50 MiB file flushed while 8 KiB are appended and fdatasync'ed every 2 ms to another file;\n");
  std::printf("flush_to_disk's step: %lld KiB\n\n", static_cast<long long>(kFlushStep >> 10));
  std::printf("| %-14s | %22s | %22s | %22s | %22s | %8s |\n", "large flush", "its time, median ms",
              "small flush p50 ms", "small flush p99 ms", "small flush max ms", "smalls");
  std::printf("|---|---|---|---|---|---|\n");
  for (const Variant& v : variants)
    std::printf("| %-14s | %22.1f | %22.2f | %22.2f | %22.2f | %8zu |\n", v.name, percentile(v.big_ms, 0.5),
                percentile(v.small_ms, 0.5), percentile(v.small_ms, 0.99),
                v.small_ms.empty() ? 0.0 : *std::max_element(v.small_ms.begin(), v.small_ms.end()),
                v.small_ms.size());
  std::printf("\nsmall flushes: those that began while the large file was being flushed.\n");
  return 0;
}
