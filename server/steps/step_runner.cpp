#include "server/steps/step_runner.h"

#include "core/image/contact_sheet.h"
#include "core/image/image.h"
#include "protocol/errors.h"
#include "server/helper_thread.h"
#include "server/steps/movie_encoder.h"
#include "server/steps/tool_path.h"

#include <spdlog/spdlog.h>

#include <algorithm>
#include <fstream>

namespace fs = std::filesystem;

namespace tessera::server {

namespace {

using protocol::Step;

// A contact sheet's cells are this wide.
constexpr int kSheetCellWidth = 256;

// "preview.png" for a one-image job, "preview.f12.png" for frame 12 of a sequence.
std::string output_name(Step step, std::optional<int64_t> frame, const char* ext) {
  return std::string(protocol::to_string(step)) + (frame ? ".f" + std::to_string(*frame) : "") + ext;
}

std::string marker(Step step, const char* what) { return "." + std::string(protocol::to_string(step)) + "." + what; }

}  // namespace

StepRunner::StepRunner(Scheduler& scheduler, JobStore& store, StepOptions options, size_t capacity)
    : sched_(scheduler), store_(store), opt_(std::move(options)), capacity_(capacity), thread_([this] { run(); }) {
  if (const std::optional<fs::path> tool = ffmpeg())
    spdlog::info("steps: the movie step runs {}", tool->string());
  else
    spdlog::info("steps: movies are refused at submission: {}", ffmpeg_missing());
}

std::optional<fs::path> StepRunner::ffmpeg() const { return find_tool(opt_.ffmpeg, process_search_path()); }

std::string StepRunner::ffmpeg_missing() const {
  if (opt_.ffmpeg.find('/') != std::string::npos)
    return "ffmpeg is not an executable file at " + opt_.ffmpeg + " (serve --ffmpeg)";
  return "'" + opt_.ffmpeg + "' is not found on the coordinator's PATH (install ffmpeg, or name it with serve --ffmpeg)";
}

bool StepRunner::stopping() {
  std::lock_guard lock(mu_);
  return stop_;
}

StepRunner::~StepRunner() {
  {
    std::lock_guard lock(mu_);
    stop_ = true;
  }
  cv_.notify_all();
  thread_.join();
}

fs::path StepRunner::dir(const std::string& job) { return store_.result_path(job).parent_path() / "steps"; }

bool StepRunner::settled(const std::string& job, Step step) {
  std::error_code ec;
  const fs::path d = dir(job);
  return fs::exists(d / marker(step, "done"), ec) || fs::exists(d / marker(step, "failed"), ec);
}

void StepRunner::job_done(const std::string& job) {
  std::optional<protocol::JobStatus> s = sched_.job(job);
  if (s && s->sequence) s = sched_.job(*s->sequence);
  if (s && s->state == JobState::done && !s->params.pipeline.then.empty()) queue(*s);
}

void StepRunner::resume() {
  for (const protocol::JobStatus& s : sched_.jobs())
    if (s.state == JobState::done && !s.params.pipeline.then.empty()) queue(s);
}

void StepRunner::queue(const protocol::JobStatus& top) {
  Work w{top.id, {}, top.params.pipeline.fps, {}};
  for (const Step step : top.params.pipeline.then)
    if (!settled(top.id, step)) w.steps.push_back(step);
  if (w.steps.empty()) return;
  if (top.frames) {
    if (const auto page = sched_.frames(top.id, std::nullopt, 0))
      for (const protocol::JobStatus& f : page->frames) w.results.emplace_back(f.frame, store_.result_path(f.id));
  } else {
    w.results.emplace_back(std::nullopt, store_.result_path(top.id));
  }
  std::unique_lock lock(mu_);
  if (busy_.count(top.id)) return;  // queued or running already
  if (queue_.size() >= capacity_) {
    lock.unlock();
    const std::string why = "not run: " + std::to_string(capacity_) + " jobs' steps were already waiting";
    spdlog::warn("job {}: steps {}", top.id, why);
    std::error_code ec;
    fs::create_directories(dir(top.id), ec);
    for (const Step step : w.steps) std::ofstream(dir(top.id) / marker(step, "failed")) << why << "\n";
    return;
  }
  busy_.insert(top.id);
  queue_.push_back(std::move(w));
  cv_.notify_all();
}

void StepRunner::run() {
  block_signals_in_helper_thread();
  std::unique_lock lock(mu_);
  while (true) {
    cv_.wait(lock, [this] { return stop_ || !queue_.empty(); });
    if (stop_) return;
    Work w = std::move(queue_.front());
    queue_.pop_front();
    lock.unlock();
    for (const Step step : w.steps)
      if (!stopping()) run_step(w, step);  // those not run are queued again after the restart (resume)
    lock.lock();
    busy_.erase(w.job);
  }
}

void StepRunner::run_step(const Work& w, Step step) {
  const fs::path d = dir(w.job);
  try {
    fs::create_directories(d);
    switch (step) {
      case Step::preview:
        for (const auto& [frame, file] : w.results)
          write_png_srgb(d / output_name(step, frame, ".png"), read_exr(file).pixels);
        break;
      case Step::half:
        for (const auto& [frame, file] : w.results) {
          ExrWriteOptions opt;
          opt.half = true;
          write_exr(d / output_name(step, frame, ".exr"), read_exr(file).pixels, opt);
        }
        break;
      case Step::contact_sheet: {
        std::vector<Image> cells;
        for (const auto& [frame, file] : w.results) cells.push_back(thumbnail(read_exr(file).pixels, kSheetCellWidth));
        write_png_srgb(d / output_name(step, std::nullopt, ".png"), contact_sheet(cells));
        break;
      }
      case Step::movie: {
        MovieJob movie;
        if (std::optional<fs::path> tool = ffmpeg()) movie.ffmpeg = std::move(*tool);
        else throw std::runtime_error("no movie: " + ffmpeg_missing());
        for (const auto& [frame, file] : w.results) movie.frames.push_back(file);
        movie.fps = w.fps;
        movie.stall_seconds = opt_.movie_stall_seconds;
        movie.output = d / output_name(step, std::nullopt, ".mp4");
        movie.log = d / marker(step, "log");
        encode_movie(movie, [this] { return stopping(); });
        break;
      }
    }
    std::ofstream(d / marker(step, "done")) << "done\n";
    spdlog::info("job {}: step {} done", w.job, protocol::to_string(step));
  } catch (const EncodeInterrupted& e) {  // neither done nor failed: made again after the restart (resume)
    spdlog::info("job {}: step {} {}", w.job, protocol::to_string(step), e.what());
  } catch (const std::exception& e) {
    spdlog::warn("job {}: step {} failed: {}", w.job, protocol::to_string(step), e.what());
    std::error_code ec;
    fs::create_directories(d, ec);
    std::ofstream(d / marker(step, "failed")) << e.what() << "\n";
  }
}

std::vector<protocol::StepOutput> StepRunner::outputs(const protocol::JobStatus& job) {
  std::vector<protocol::StepOutput> out;
  if (job.state != JobState::done) return out;
  const fs::path d = dir(job.id);
  std::error_code ec;
  std::vector<std::string> names;
  for (const auto& e : fs::directory_iterator(d, ec)) {
    const std::string n = e.path().filename().string();
    if (!n.empty() && n.front() != '.' && n.find(".tmp") == std::string::npos) names.push_back(n);
  }
  std::sort(names.begin(), names.end());
  for (const Step step : job.params.pipeline.then) {
    protocol::StepOutput o{step, "pending", {}, ""};
    if (fs::exists(d / marker(step, "done"), ec)) {
      o.state = "done";
      const std::string prefix = std::string(protocol::to_string(step)) + ".";
      for (const std::string& n : names)
        if (n.rfind(prefix, 0) == 0) o.files.push_back(n);
    } else if (std::ifstream in(d / marker(step, "failed")); in) {
      o.state = "failed";
      std::getline(in, o.log, '\0');
      while (!o.log.empty() && o.log.back() == '\n') o.log.pop_back();
    }
    out.push_back(std::move(o));
  }
  return out;
}

fs::path StepRunner::output_file(const std::string& id, const std::string& name) {
  const std::optional<protocol::JobStatus> s = sched_.job(id);
  if (!s) throw protocol::ApiError(404, "no job " + id);
  for (const protocol::StepOutput& o : outputs(*s))
    if (std::find(o.files.begin(), o.files.end(), name) != o.files.end()) return dir(id) / name;
  throw protocol::ApiError(404, "job " + id + " has no output " + name);
}

}  // namespace tessera::server
