// A submission's pipeline fields: read and written back, and the sentences that refuse bad ones.
#include "protocol/messages.h"

#include <gtest/gtest.h>

namespace tessera::protocol {
namespace {

using nlohmann::json;

std::string pipeline_refusal(const std::string& body) {
  try {
    parse_job_submission(body);
  } catch (const ProtocolError& e) {
    return e.what();
  }
  return "(accepted)";
}

TEST(PipelineFields, ASubmissionsPipelineRoundTrips) {
  const JobSubmission s = parse_job_submission(
      R"({"frames": [{"number": 1, "scene": {}}], "after": ["j-1", "j-2", "j-1"], "per_frame": true,
          "then": ["movie", "preview"], "fps": 30, "notify": "https://hooks.example/x", "notify_frames": true})");
  EXPECT_EQ(s.pipeline.after, (std::vector<std::string>{"j-1", "j-2"}));  // a repeated id once
  EXPECT_TRUE(s.pipeline.per_frame);
  EXPECT_EQ(s.pipeline.then, (std::vector<Step>{Step::movie, Step::preview}));
  EXPECT_EQ(s.pipeline.notify, "https://hooks.example/x");
  EXPECT_EQ(s.pipeline.fps, 30);
  EXPECT_TRUE(s.pipeline.notify_frames);
  const JobSubmission back = parse_job_submission(json(s).dump());
  EXPECT_EQ(back.pipeline.after, s.pipeline.after);
  EXPECT_EQ(back.pipeline.then, s.pipeline.then);
  EXPECT_TRUE(back.pipeline.per_frame);
  EXPECT_EQ(back.pipeline.fps, 30);
  EXPECT_TRUE(back.pipeline.notify_frames);
  EXPECT_EQ(answer_pipeline(json(s)).fps, 30);  // a job's answer (and its stored row) carries them too
  EXPECT_TRUE(answer_pipeline(json(s)).notify_frames);
  // A job without any writes none of the fields.
  const json plain = json(parse_job_submission(R"({"scene": {}})"));
  for (const char* k : {"after", "per_frame", "then", "fps", "notify", "notify_frames"}) EXPECT_FALSE(plain.contains(k)) << k;
}

TEST(PipelineFields, BadPipelinesAreRefusedWithASentence) {
  EXPECT_EQ(pipeline_refusal(R"({"scene": {}, "after": "j-1"})"), "\"after\" must be an array of strings");
  EXPECT_EQ(pipeline_refusal(R"({"scene": {}, "after": [""]})"), "\"after\" names a job id of 0 bytes; ids have 1 to 200");
  EXPECT_EQ(pipeline_refusal(R"({"scene": {}, "after": ["j-1"], "per_frame": true})"),
            "'per_frame' applies only to a sequence ('frames'): frame k waits for frame k of each job in 'after'");
  EXPECT_EQ(pipeline_refusal(R"({"frames": [{"number": 1, "scene": {}}], "per_frame": true})"),
            "'per_frame' needs 'after': it says how a sequence waits for the jobs it names");
  EXPECT_EQ(pipeline_refusal(R"({"scene": {}, "then": ["shell"]})"),
            "\"then\" names an unknown step 'shell' (the steps are preview, half, contact_sheet, movie)");
  EXPECT_EQ(pipeline_refusal(R"({"scene": {}, "then": ["half", "half"]})"), "\"then\" names the step 'half' twice");
  EXPECT_EQ(pipeline_refusal(R"({"scene": {}, "notify": 5})"), "'notify' must be a URL string (got 5)");
  EXPECT_EQ(pipeline_refusal(R"({"frames": [{"number": 1, "scene": {}}], "fps": 30})"),
            "'fps' is the frame rate of the movie step: it needs \"then\" to name movie");
  EXPECT_EQ(pipeline_refusal(R"({"frames": [{"number": 1, "scene": {}}], "then": ["movie"], "fps": 0})"),
            "'fps' must be an integer in 1..240 (got 0)");
  EXPECT_EQ(pipeline_refusal(R"({"frames": [{"number": 1, "scene": {}}], "notify_frames": true})"),
            "'notify_frames' needs 'notify': each frame done is told to the job's own address");
  EXPECT_EQ(pipeline_refusal(R"({"scene": {}, "notify": "https://h.example/x", "notify_frames": true})"),
            "'notify_frames' applies only to a sequence ('frames'): it tells of each frame done");
}

TEST(PipelineFields, AJobCarriesItsDependenciesDependentsAndReason) {
  JobStatus s;
  s.id = "j-3";
  s.state = JobState::blocked;
  s.params.pipeline.after = {"j-1"};
  s.dependents = {"j-4"};
  s.reason = "dependency j-1 failed: boom";
  const json j = json(s);
  EXPECT_EQ(j["state"], "blocked");
  EXPECT_EQ(j["after"], json::array({"j-1"}));
  EXPECT_EQ(j["dependents"], json::array({"j-4"}));
  const JobStatus back = j.get<JobStatus>();
  EXPECT_EQ(back.state, JobState::blocked);
  EXPECT_EQ(back.params.pipeline.after, s.params.pipeline.after);
  EXPECT_EQ(back.dependents, s.dependents);
  EXPECT_EQ(back.reason, s.reason);
}

}  // namespace
}  // namespace tessera::protocol
