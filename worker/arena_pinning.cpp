#include "worker/arena_pinning.h"

#include <sched.h>

#include <stdexcept>
#include <algorithm>

namespace tessera::worker {

namespace {

// The CPU set a thread had when it entered the arena, given back when it leaves (one arena per thread at a time).
thread_local cpu_set_t t_before;
thread_local bool t_saved = false;

}  // namespace

std::vector<int> allowed_cpus() {
  cpu_set_t set;
  CPU_ZERO(&set);
  std::vector<int> cpus;
  if (sched_getaffinity(0, sizeof set, &set) != 0) return cpus;
  for (int c = 0; c < CPU_SETSIZE; ++c)
    if (CPU_ISSET(c, &set)) cpus.push_back(c);
  return cpus;
}

std::vector<int> parse_cpu_list(const std::string& text) {
  std::vector<int> cpus;
  const auto number = [&](size_t& i) {
    if (i >= text.size() || text[i] < '0' || text[i] > '9')
      throw std::invalid_argument("CPU list '" + text + "': expected a CPU number at position " + std::to_string(i + 1));
    int v = 0;
    while (i < text.size() && text[i] >= '0' && text[i] <= '9') {
      v = v * 10 + (text[i++] - '0');
      if (v >= CPU_SETSIZE) throw std::invalid_argument("CPU list '" + text + "': CPU numbers go up to " + std::to_string(CPU_SETSIZE - 1));
    }
    return v;
  };
  size_t i = 0;
  while (true) {
    const int first = number(i);
    int last = first;
    if (i < text.size() && text[i] == '-') {
      ++i;
      last = number(i);
      if (last < first) throw std::invalid_argument("CPU list '" + text + "': range " + std::to_string(first) + "-" + std::to_string(last) + " runs backwards");
    }
    for (int c = first; c <= last; ++c) cpus.push_back(c);
    if (i == text.size()) break;
    if (text[i] != ',') throw std::invalid_argument("CPU list '" + text + "': unexpected '" + text[i] + "' at position " + std::to_string(i + 1));
    ++i;
  }
  std::sort(cpus.begin(), cpus.end());
  cpus.erase(std::unique(cpus.begin(), cpus.end()), cpus.end());
  return cpus;
}

ArenaPinning::ArenaPinning(tbb::task_arena& arena, std::vector<int> cpus)
    : tbb::task_scheduler_observer(arena), cpus_(std::move(cpus)) {
  if (cpus_.empty()) throw std::invalid_argument("ArenaPinning needs at least one CPU");
  observe(true);
}

ArenaPinning::~ArenaPinning() { observe(false); }

void ArenaPinning::on_scheduler_entry(bool) {
  const int slot = tbb::this_task_arena::current_thread_index();
  if (slot < 0) return;
  t_saved = sched_getaffinity(0, sizeof t_before, &t_before) == 0;
  cpu_set_t one;
  CPU_ZERO(&one);
  CPU_SET(cpus_[size_t(slot) % cpus_.size()], &one);
  sched_setaffinity(0, sizeof one, &one);  // best effort: a CPU taken away since start-up leaves the thread as it was
}

void ArenaPinning::on_scheduler_exit(bool) {
  if (t_saved) sched_setaffinity(0, sizeof t_before, &t_before);
  t_saved = false;
}

}  // namespace tessera::worker
