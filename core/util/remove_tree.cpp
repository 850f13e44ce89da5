#include "core/util/remove_tree.h"

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <mutex>
#include <thread>
#include <vector>

#include <unistd.h>

namespace fs = std::filesystem;

namespace tessera {

namespace {

// At most this many threads remove entries at once: enough to overlap the disk's waits of a scratch tree's folders.
constexpr size_t kMaxThreads = 16;

// Removes every path of `paths` (files with unlink, folders with rmdir), several at a time; the first error goes to ec.
void remove_all_of(const std::vector<fs::path>& paths, bool folders, std::atomic<std::uintmax_t>& removed,
                   std::error_code& ec, std::mutex& ec_mutex) {
  std::atomic<size_t> next{0};
  const auto work = [&] {
    for (size_t i = next.fetch_add(1); i < paths.size(); i = next.fetch_add(1)) {
      if ((folders ? ::rmdir(paths[i].c_str()) : ::unlink(paths[i].c_str())) == 0) {
        removed.fetch_add(1);
      } else if (errno != ENOENT) {
        const int err = errno;
        std::lock_guard lock(ec_mutex);
        if (!ec) ec = std::error_code(err, std::generic_category());
      }
    }
  };
  const size_t n = std::min(kMaxThreads, paths.size());
  std::vector<std::thread> threads;
  threads.reserve(n > 0 ? n - 1 : 0);
  try {
    for (size_t t = 1; t < n; ++t) threads.emplace_back(work);
  } catch (const std::system_error&) {
    // no more threads: the ones started and this one share the rest
  }
  work();
  for (std::thread& t : threads) t.join();
}

}  // namespace

std::uintmax_t remove_tree(const fs::path& dir, std::error_code& ec) {
  ec.clear();
  const fs::file_status st = fs::symlink_status(dir, ec);
  if (ec) {
    if (ec == std::errc::no_such_file_or_directory) ec.clear();
    return 0;
  }
  if (!fs::is_directory(st)) return fs::remove(dir, ec) ? 1 : 0;
  std::vector<fs::path> files;
  std::vector<std::vector<fs::path>> folders_by_depth;  // below dir: [0] its own folders, [1] theirs, ...
  for (auto it = fs::recursive_directory_iterator(dir, ec); !ec && it != fs::recursive_directory_iterator();
       it.increment(ec)) {
    std::error_code tec;
    if (it->is_directory(tec) && !it->is_symlink(tec)) {
      const size_t depth = size_t(it.depth());
      if (folders_by_depth.size() <= depth) folders_by_depth.resize(depth + 1);
      folders_by_depth[depth].push_back(it->path());
    } else {
      files.push_back(it->path());
    }
  }
  if (ec) return 0;
  std::atomic<std::uintmax_t> removed{0};
  std::mutex ec_mutex;
  remove_all_of(files, false, removed, ec, ec_mutex);
  if (ec) return removed.load();
  // Emptied of files, the deeper folders are moved up beside the others (a rename frees nothing, so it does not wait),
  // deepest first, so that every folder is then removed in one parallel round instead of one round per depth.
  std::vector<fs::path> folders;
  size_t moved = 0;
  bool moving = true;  // until a move fails: then the folders not moved yet stay where they are (their paths hold)
  for (size_t depth = folders_by_depth.size(); depth-- > 0;)
    for (const fs::path& f : folders_by_depth[depth]) {
      if (depth > 0 && moving) {
        fs::path up = dir / (".removing-" + std::to_string(moved++));
        if (::rename(f.c_str(), up.c_str()) == 0) {
          folders.push_back(std::move(up));
          continue;
        }
        moving = false;
      }
      folders.push_back(f);
    }
  // Folders left in place come after their children: if the parallel round could not remove one (its children were
  // going at the same time), a pass in this order removes the rest one by one.
  remove_all_of(folders, true, removed, ec, ec_mutex);
  if (ec && ec == std::errc::directory_not_empty) {
    ec.clear();
    for (const fs::path& f : folders)
      if (::rmdir(f.c_str()) == 0) removed.fetch_add(1);
      else if (errno != ENOENT && !ec) ec = std::error_code(errno, std::generic_category());
  }
  if (!ec) {
    if (::rmdir(dir.c_str()) == 0) removed.fetch_add(1);
    else ec = std::error_code(errno, std::generic_category());
  }
  return removed.load();
}

}  // namespace tessera
