#include "server/outbox.h"

#include "protocol/routes.h"
#include "protocol/webhook.h"
#include "server/farm_state.h"

#include <nlohmann/json.hpp>

namespace tessera::server {

void note_job_event(FarmState& s, const JobRec& top, JobState was, int64_t now) {
  const JobState st = s.state_of(top);
  if (st == was || !(is_final(st) || st == JobState::blocked)) return;
  std::vector<std::string> urls = s.config.webhooks;
  const std::string& own = top.status.params.pipeline.notify;
  if (!own.empty() && std::find(urls.begin(), urls.end(), own) == urls.end()) urls.push_back(own);
  if (urls.empty()) return;
  const std::string id = s.next_id('e');
  const std::string event = std::string("job.") + protocol::to_string(st);
  const std::string& job = top.status.id;
  nlohmann::json links = {{"job", protocol::routes::job(job)}};
  if (st == JobState::done)
    links[top.is_sequence() ? "frames" : "result"] =
        top.is_sequence() ? protocol::routes::job_frames(job) : protocol::routes::job_result(job);
  const nlohmann::json body = {
      {"id", id}, {"event", event}, {"created_ms", now}, {"job", s.snapshot(top, now)}, {"links", links}};
  const std::string text = body.dump();
  for (const std::string& url : urls) s.changes.add_outbox(OutboxRow{id, url, event, job, now, text});
}

void note_frame_event(FarmState& s, const JobRec& top, const JobRec& frame, int64_t now) {
  const protocol::Pipeline& p = top.status.params.pipeline;
  if (!p.notify_frames || p.notify.empty() || !frame.status.frame) return;
  const std::string id = s.next_id('e');
  const std::string event(protocol::kFrameDoneWebhookEvent);
  const std::string& job = top.status.id;
  const int64_t number = *frame.status.frame;
  const nlohmann::json links = {{"job", protocol::routes::job(job)},
                                {"frame", protocol::routes::job(frame.status.id)},
                                {"result", protocol::routes::job_frame_result(job, number)}};
  const nlohmann::json body = {{"id", id},         {"event", event}, {"created_ms", now},
                               {"frame", number},  {"job", s.snapshot(frame, now)}, {"links", links}};
  s.changes.add_outbox(OutboxRow{id, p.notify, event, job, now, body.dump()});
}

}  // namespace tessera::server
