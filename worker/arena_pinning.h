// Pinning the threads of a render arena to CPUs, for a worker that is given the machine's cores.
#pragma once

#include <tbb/task_arena.h>
#include <tbb/task_scheduler_observer.h>

#include <string>
#include <vector>

namespace tessera::worker {

/// The CPUs this process may run on (sched_getaffinity), in ascending order.
std::vector<int> allowed_cpus();

/// Parses a CPU list such as "0-3,6" into ascending, distinct CPU numbers; throws std::invalid_argument naming what
/// is wrong (syntax, a CPU above 1023, an empty list).
std::vector<int> parse_cpu_list(const std::string& text);

/// While a thread works in `arena`, it runs only on one CPU of `cpus`: the thread in the arena's slot i on
/// cpus[i % cpus.size()]. A thread leaving the arena gets back the CPUs it had before. Render threads that sleep
/// between tiles are otherwise woken wherever the kernel chooses, and on a 2-core VM both were seen sharing one core
/// for 20-30 ms while the other stayed idle; with one thread per core that cannot happen.
class ArenaPinning : public tbb::task_scheduler_observer {
 public:
  /// Observes `arena` (which must outlive this) from now on; `cpus` must not be empty.
  ArenaPinning(tbb::task_arena& arena, std::vector<int> cpus);
  ~ArenaPinning() override;

  void on_scheduler_entry(bool is_worker) override;
  void on_scheduler_exit(bool is_worker) override;

 private:
  std::vector<int> cpus_;
};

}  // namespace tessera::worker
