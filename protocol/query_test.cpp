// The query strings of job listings, frame listings and purges: what they accept, the sentences they refuse with, and
// the round trip of the clients' builder.
#include "protocol/query.h"

#include "protocol/errors.h"
#include "protocol/sequence.h"

#include <gtest/gtest.h>

namespace tessera::protocol {
namespace {

std::string refusal(const std::string& target) {
  try {
    parse_job_list_query(target);
  } catch (const ProtocolError& e) {
    return e.what();
  }
  return "accepted";
}

TEST(JobListQuery, ParsesStatesLimitAndCursor) {
  const JobListQuery q = parse_job_list_query("/v1/jobs?state=done,failed&limit=20&after=c%2012");
  EXPECT_EQ(q.states, (std::vector<JobState>{JobState::done, JobState::failed}));
  EXPECT_EQ(q.limit, 20u);
  EXPECT_EQ(q.after, "c 12");
  EXPECT_TRUE(parse_job_list_query("/v1/jobs").states.empty());
  EXPECT_EQ(parse_job_list_query("/v1/jobs?").limit, 0u);
  EXPECT_EQ(parse_job_list_query(std::string("/v1/jobs") + q.to_query()).after, "c 12");
  EXPECT_EQ(q.to_query(), "?state=done,failed&limit=20&after=c%2012");
  EXPECT_EQ(JobListQuery{}.to_query(), "");
}

TEST(JobListQuery, BadValuesAreRefusedWithASentence) {
  EXPECT_NE(refusal("/v1/jobs?state=finished").find("'finished' is not a job state"), std::string::npos);
  EXPECT_NE(refusal("/v1/jobs?state=").find("is not a job state"), std::string::npos);
  EXPECT_NE(refusal("/v1/jobs?limit=0").find("limit: '0' is not a whole number from 1 to 10000"), std::string::npos);
  EXPECT_NE(refusal("/v1/jobs?limit=-3").find("limit"), std::string::npos);
  EXPECT_NE(refusal("/v1/jobs?limit=10001").find("limit"), std::string::npos);
  EXPECT_NE(refusal("/v1/jobs?limit=1e3").find("limit"), std::string::npos);
  EXPECT_NE(refusal("/v1/jobs?after=").find("after: empty"), std::string::npos);
  EXPECT_NE(refusal("/v1/jobs?sort=name").find("unknown query parameter 'sort'"), std::string::npos);
  EXPECT_NE(refusal("/v1/jobs?limit=1&limit=2").find("more than once"), std::string::npos);
  EXPECT_NE(refusal("/v1/jobs?after=%zz").find("bad percent-escape"), std::string::npos);
  EXPECT_NE(refusal("/v1/jobs?after=%4").find("bad percent-escape"), std::string::npos);
  EXPECT_NE(refusal("/v1/jobs?after=a%0Ab").find("a control character (%0A)"), std::string::npos);
}

TEST(PurgeQuery, OnlyTrueOrFalse) {
  EXPECT_FALSE(parse_purge_query("/v1/jobs/j-1"));
  EXPECT_FALSE(parse_purge_query("/v1/jobs/j-1?purge=false"));
  EXPECT_TRUE(parse_purge_query("/v1/jobs/j-1?purge=true"));
  EXPECT_THROW(parse_purge_query("/v1/jobs/j-1?purge=yes"), ProtocolError);
  EXPECT_THROW(parse_purge_query("/v1/jobs/j-1?purge"), ProtocolError);
  EXPECT_THROW(parse_purge_query("/v1/jobs/j-1?force=true"), ProtocolError);
}


std::string frame_list_refusal(const std::string& target) {
  try {
    parse_frame_list_query(target);
  } catch (const ProtocolError& e) {
    return e.what();
  }
  return "accepted";
}

TEST(FrameListQuery, ParsesAfterAndLimit) {
  const FrameListQuery all = parse_frame_list_query("/v1/jobs/j-4/frames");
  EXPECT_FALSE(all.after);
  EXPECT_EQ(all.limit, 0u);  // every frame
  const FrameListQuery q = parse_frame_list_query("/v1/jobs/j-4/frames?after=12&limit=50");
  EXPECT_EQ(q.after, 12);
  EXPECT_EQ(q.limit, 50u);
  EXPECT_EQ(parse_frame_list_query("/v1/jobs/j-4/frames?limit=3").after, std::nullopt);
  EXPECT_EQ(parse_frame_list_query("/v1/jobs/j-4/frames?after=-1").after, -1);  // before frame 0: from the first
  EXPECT_EQ(parse_frame_list_query("/v1/jobs/j-4/frames?after=0").after, 0);
  EXPECT_EQ(parse_frame_list_query("/v1/jobs/j-4/frames?after=999999999").after, kMaxFrameNumber);
  EXPECT_EQ(parse_frame_list_query("/v1/jobs/j-4/frames?limit=1").limit, 1u);
  EXPECT_EQ(parse_frame_list_query("/v1/jobs/j-4/frames?limit=10000").limit, 10000u);
  EXPECT_EQ(parse_frame_list_query("/v1/jobs/j-4/frames?").limit, 0u);
  // The clients' builder: "" at the defaults, and what it builds parses back.
  EXPECT_EQ(FrameListQuery{}.to_query(), "");
  EXPECT_EQ(q.to_query(), "?after=12&limit=50");
  EXPECT_EQ((FrameListQuery{.after = std::nullopt, .limit = 7}).to_query(), "?limit=7");
  EXPECT_EQ((FrameListQuery{.after = -1, .limit = 0}).to_query(), "?after=-1");
  for (const FrameListQuery& built : {q, FrameListQuery{.after = std::nullopt, .limit = 7},
                                      FrameListQuery{.after = 0, .limit = 0}, FrameListQuery{}}) {
    const FrameListQuery back = parse_frame_list_query("/v1/jobs/j-4/frames" + built.to_query());
    EXPECT_EQ(back.after, built.after);
    EXPECT_EQ(back.limit, built.limit);
  }
}

TEST(FrameListQuery, BadValuesAreRefusedWithASentence) {
  EXPECT_EQ(frame_list_refusal("/v1/jobs/j-4/frames?limit=0"), "limit: '0' is not a whole number from 1 to 10000");
  EXPECT_EQ(frame_list_refusal("/v1/jobs/j-4/frames?limit=10001"),
            "limit: '10001' is not a whole number from 1 to 10000");
  EXPECT_EQ(frame_list_refusal("/v1/jobs/j-4/frames?limit=-1"), "limit: '-1' is not a whole number from 1 to 10000");
  EXPECT_EQ(frame_list_refusal("/v1/jobs/j-4/frames?limit="), "limit: '' is not a whole number from 1 to 10000");
  EXPECT_EQ(frame_list_refusal("/v1/jobs/j-4/frames?limit=2.5"), "limit: '2.5' is not a whole number from 1 to 10000");
  EXPECT_EQ(frame_list_refusal("/v1/jobs/j-4/frames?after=-2"),
            "after: '-2' is not a whole number from -1 to 999999999");
  EXPECT_EQ(frame_list_refusal("/v1/jobs/j-4/frames?after=1000000000"),
            "after: '1000000000' is not a whole number from -1 to 999999999");
  EXPECT_EQ(frame_list_refusal("/v1/jobs/j-4/frames?after=99999999999999999999"),
            "after: '99999999999999999999' is not a whole number from -1 to 999999999");
  EXPECT_EQ(frame_list_refusal("/v1/jobs/j-4/frames?after=c12"),
            "after: 'c12' is not a whole number from -1 to 999999999");
  EXPECT_EQ(frame_list_refusal("/v1/jobs/j-4/frames?after=%2B3"),  // '+' alone decodes as a space
            "after: '+3' is not a whole number from -1 to 999999999");
  EXPECT_EQ(frame_list_refusal("/v1/jobs/j-4/frames?after=3%20"),
            "after: '3 ' is not a whole number from -1 to 999999999");
  EXPECT_EQ(frame_list_refusal("/v1/jobs/j-4/frames?after="), "after: '' is not a whole number from -1 to 999999999");
  EXPECT_NE(frame_list_refusal("/v1/jobs/j-4/frames?state=done").find("unknown query parameter 'state'"),
            std::string::npos);
  EXPECT_NE(frame_list_refusal("/v1/jobs/j-4/frames?after=1&after=2").find("more than once"), std::string::npos);
  EXPECT_NE(frame_list_refusal("/v1/jobs/j-4/frames?after=%zz").find("bad percent-escape"), std::string::npos);
}

}  // namespace
}  // namespace tessera::protocol

namespace tessera::protocol {
namespace {

TEST(PreviewQuery, ALayerByNameOrNone) {
  EXPECT_FALSE(parse_preview_query("/v1/jobs/j/preview.png"));
  EXPECT_EQ(parse_preview_query("/v1/jobs/j/preview.png?layer=normal"), Layer::kNormal);
  EXPECT_THROW(parse_preview_query("/v1/jobs/j/preview.png?layer=beauty"), ProtocolError);
  EXPECT_THROW(parse_preview_query("/v1/jobs/j/preview.png?size=2"), ProtocolError);
}

}  // namespace
}  // namespace tessera::protocol
