// Saving a sequence's frames while it renders: each done frame once, to its file of an output pattern.
#pragma once

#include "client/http_client.h"
#include "protocol/job.h"

#include <cstdint>
#include <functional>
#include <set>
#include <string>

namespace tessera::cli {

/// Puts a done job's result (or a frame's: `job` is then the frame's job, `frame` its number) at `output` and
/// returns its size in bytes; throws on failure.
using ResultFetch = std::function<uint64_t(const std::string& job, const std::string& output, int64_t frame)>;

/// Saves the done frames of one sequence to `pattern` (cli/frame_list.h frame_output), each once, as they finish.
class FrameSaver {
 public:
  /// Saves frames of `sequence` through `http` (or `fetch`, when given, with each frame's job id).
  FrameSaver(client::HttpClient& http, std::string sequence, std::string pattern, ResultFetch fetch, bool quiet);
  /// Saves the frames done in `status` (the sequence as it is now) that are not saved yet; returns how many it saved.
  /// Throws what the download or the fetch throws.
  int64_t update(const protocol::JobStatus& status);
  /// Frames saved so far.
  int64_t saved() const { return int64_t(saved_.size()); }

 private:
  client::HttpClient& http_;
  std::string sequence_;
  std::string pattern_;
  ResultFetch fetch_;
  bool quiet_;
  std::set<int64_t> saved_;  // frame numbers
  int64_t below_ = -1;       // every frame numbered at most this is saved (where the next scan starts)
};

}  // namespace tessera::cli
