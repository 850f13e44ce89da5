// The webhook outbox (docs/operations.md, "Webhooks"): when a job ends or is blocked (or, when asked, a sequence's
// frame is done), one row per destination is written with the change that caused it, in the same transaction, so
// that a coordinator killed before the delivery still delivers it after a restart (server/webhook_sender.h sends
// them).
#pragma once

#include "server/scheduler_types.h"

#include <cstdint>
#include <string>
#include <vector>

namespace tessera::server {

struct FarmState;
struct JobRec;

/// One event for one destination, as the scheduler writes it.
struct OutboxRow {
  std::string id;          ///< The event id (shared by its destinations).
  std::string url;         ///< The destination.
  std::string event;       ///< e.g. "job.done".
  std::string job;         ///< The job it is about.
  int64_t created_ms = 0;  ///< When it happened.
  std::string body;        ///< The JSON POSTed.
};

/// After an operation changed job `top` (a one-image job or a sequence, never a frame) from state `was`: when it is
/// now done, failed, cancelled or blocked, an event for each destination (the farm's webhooks and the job's own
/// address) goes to the change log, stored with the operation's other changes.
void note_job_event(FarmState& s, const JobRec& top, JobState was, int64_t now);

/// After frame `frame` of sequence `top` was done: when the sequence was submitted with notify_frames, a frame.done
/// event for the sequence's own address goes to the change log, stored with the frame's completion.
void note_frame_event(FarmState& s, const JobRec& top, const JobRec& frame, int64_t now);

}  // namespace tessera::server
