// The query strings of job listings and purges: what they accept, the sentences they refuse with, and the round trip
// of the clients' builder.
#include "protocol/query.h"

#include "protocol/errors.h"

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

}  // namespace
}  // namespace tessera::protocol
