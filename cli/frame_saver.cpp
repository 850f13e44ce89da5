#include "cli/frame_saver.h"

#include "cli/frame_list.h"
#include "client/job_client.h"

#include <cstdio>

#include <unistd.h>

namespace tessera::cli {

FrameSaver::FrameSaver(client::HttpClient& http, std::string sequence, std::string pattern, ResultFetch fetch,
                       bool quiet)
    : http_(http), sequence_(std::move(sequence)), pattern_(std::move(pattern)), fetch_(std::move(fetch)),
      quiet_(quiet) {}

int64_t FrameSaver::update(const protocol::JobStatus& status) {
  if (!status.frames || status.frames->done <= saved()) return 0;
  // The frames not saved yet lie above below_: pages from there until every done frame is saved (in order, the new
  // ones are the first few).
  int64_t saved_now = 0;
  bool unbroken = true;  // every frame listed so far is saved
  protocol::FrameListQuery q;
  q.limit = 256;
  q.after = below_;
  while (saved() < status.frames->done) {
    const protocol::FrameList page = client::list_frames(http_, sequence_, q);
    for (const protocol::JobStatus& f : page.frames) {
      const int64_t n = f.frame.value_or(0);
      if (f.state == protocol::JobState::done && !saved_.count(n)) {
        const std::string out = frame_output(pattern_, n, size_t(status.frames->total)).string();
        const uint64_t bytes = fetch_ ? fetch_(f.id, out, n) : client::download_frame(http_, sequence_, n, out);
        saved_.insert(n);
        ++saved_now;
        if (!quiet_)
          std::fprintf(stderr, "%sframe %lld: %s (%dx%d, %llu bytes)\n", isatty(STDERR_FILENO) ? "\n" : "",
                       static_cast<long long>(n), out.c_str(),
                       f.params.width, f.params.height, static_cast<unsigned long long>(bytes));
      }
      unbroken = unbroken && saved_.count(n);
      if (unbroken) below_ = n;
    }
    if (!page.next) break;
    q.after = page.next;
  }
  return saved_now;
}

}  // namespace tessera::cli
