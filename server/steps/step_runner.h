// The built-in steps run on a finished job's result (docs/operations.md, "Steps after the merge"): a full-size
// tone-mapped PNG (preview), a half-float copy of the EXR (half), for a sequence a contact sheet of its frames
// (contact_sheet) and an H.264 MP4 of its frames (movie, made by ffmpeg: server/steps/movie_encoder.h). They run on
// one thread of their own from a bounded queue, never on a request's; each writes its files under
// DIR/jobs/<id>/steps/ and then a marker saying it is done, or one holding its log when it failed (the render stays
// done). No command but the configured ffmpeg ever runs.
#pragma once

#include "protocol/job.h"
#include "server/scheduler.h"
#include "server/storage.h"

#include <condition_variable>
#include <cstddef>
#include <deque>
#include <filesystem>
#include <mutex>
#include <optional>
#include <set>
#include <string>
#include <thread>
#include <utility>
#include <vector>

namespace tessera::server {

/// How the steps are run.
struct StepOptions {
  /// The movie step's encoder (`serve --ffmpeg`): a path, or a name looked up on the coordinator's PATH.
  std::string ffmpeg = "ffmpeg";
  /// `serve --movie-stall-seconds`: an ffmpeg that reads no frame, or does not exit once fed, for this long is killed
  /// and the movie step failed.
  double movie_stall_seconds = 600;
};

/// Runs the steps of done jobs.
class StepRunner {
 public:
  /// Jobs whose steps wait at most (beyond them a job's steps fail at once with that reason).
  static constexpr size_t kDefaultCapacity = 64;
  /// A runner over the scheduler's jobs and the store's results (both must outlive it).
  StepRunner(Scheduler& scheduler, JobStore& store, StepOptions options = {}, size_t capacity = kDefaultCapacity);
  ~StepRunner();
  StepRunner(const StepRunner&) = delete;
  StepRunner& operator=(const StepRunner&) = delete;

  /// A job (or a frame) was done and its result written: queues the steps of the job it ends (the frame's sequence
  /// once every frame is done) when that job has steps.
  void job_done(const std::string& job);
  /// After a restart: queues the steps of every done job whose steps neither finished nor failed.
  void resume();
  /// Each step's state and files, for a done job with steps (else nothing).
  std::vector<protocol::StepOutput> outputs(const protocol::JobStatus& job);
  /// The file of output `name` of job `id`; throws protocol::ApiError 404 for a name its steps did not write.
  std::filesystem::path output_file(const std::string& id, const std::string& name);
  /// The ffmpeg the movie step would run now; nothing when StepOptions::ffmpeg names no executable file.
  std::optional<std::filesystem::path> ffmpeg() const;
  /// Why there is no ffmpeg (a sentence naming what was looked for, and where).
  std::string ffmpeg_missing() const;

 private:
  struct Work {
    std::string job;                                                     // the job whose steps run
    std::vector<protocol::Step> steps;                                   // in order
    int fps = protocol::kDefaultMovieFps;                                // the movie's frame rate
    std::vector<std::pair<std::optional<int64_t>, std::filesystem::path>> results;  // (frame, result EXR)
  };
  void queue(const protocol::JobStatus& top);
  void run();
  void run_step(const Work& w, protocol::Step step);
  std::filesystem::path dir(const std::string& job);
  bool settled(const std::string& job, protocol::Step step);  // done or failed on disk

  bool stopping();

  Scheduler& sched_;
  JobStore& store_;
  const StepOptions opt_;
  const size_t capacity_;
  std::mutex mu_;
  std::condition_variable cv_;
  std::deque<Work> queue_;     // (mu_)
  std::set<std::string> busy_;  // jobs queued or running (mu_)
  bool stop_ = false;           // (mu_)
  std::thread thread_;
};

}  // namespace tessera::server
