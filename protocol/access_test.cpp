// Roles, tags and the shared farm's request fields: what each role may call, the monitor's controls by role, tag
// lists and their refusals, and a submission's requirements and cap.
#include "protocol/access.h"
#include "protocol/errors.h"
#include "protocol/messages.h"
#include "protocol/query.h"
#include "protocol/tags.h"

#include <gtest/gtest.h>

namespace tessera::protocol {
namespace {

TEST(Roles, EachAccessAdmitsItsRoles) {
  const auto allows = [](Role r) {
    std::string out;
    for (Access a : {Access::open, Access::read, Access::submit, Access::owner, Access::admin, Access::worker,
                     Access::either})
      out += role_allows(r, a) ? '1' : '0';
    return out;
  };
  EXPECT_EQ(allows(Role::admin), "1111101");
  EXPECT_EQ(allows(Role::user), "1111001");
  EXPECT_EQ(allows(Role::viewer), "1100001");
  EXPECT_EQ(allows(Role::worker), "1000011");
  EXPECT_EQ(role_from_string("viewer"), Role::viewer);
  EXPECT_THROW(role_from_string("boss"), std::invalid_argument);
}

TEST(Roles, TheMonitorsControlsFollowTheRouteTable) {
  const Me user = me_for("ben", Role::user);
  EXPECT_EQ(user.controls.at("pause"), "own");
  EXPECT_EQ(user.controls.at("purge"), "own");
  EXPECT_EQ(user.controls.at("drain"), "none");
  EXPECT_EQ(user.controls.at("events"), "any");
  const Me admin = me_for("ana", Role::admin);
  EXPECT_EQ(admin.controls.at("pause"), "any");
  EXPECT_EQ(admin.controls.at("audit"), "any");
  const Me viewer = me_for("cy", Role::viewer);
  EXPECT_EQ(viewer.controls.at("pause"), "none");
  EXPECT_EQ(viewer.controls.at("workers"), "any");
  // Every capability of the route table is in the answer.
  EXPECT_EQ(user.controls.size(), capabilities(true).endpoints.size());
  const Me back = nlohmann::json(user).get<Me>();
  EXPECT_EQ(back.user, "ben");
  EXPECT_EQ(back.role, Role::user);
  EXPECT_EQ(back.controls, user.controls);
}

TEST(Tags, ListsAreCheckedSortedAndDeduplicated) {
  EXPECT_EQ(parse_tag_list("site-a,bigmem,gpu,bigmem", "--tags"), (std::vector<std::string>{"bigmem", "gpu", "site-a"}));
  EXPECT_TRUE(parse_tag_list("", "--tags").empty());
  EXPECT_EQ(tag_problem("gpu.v100_x-2"), "");
  EXPECT_NE(tag_problem("Big Mem").find("may contain only"), std::string::npos);
  EXPECT_NE(tag_problem("").find("empty"), std::string::npos);
  EXPECT_NE(tag_problem(std::string(65, 'a')).find("at most 64"), std::string::npos);
  EXPECT_THROW(parse_tag_list("gpu,,bigmem", "--tags"), ProtocolError);
  std::string many;
  for (int i = 0; i < 33; ++i) many += (i ? "," : "") + std::string("t") + std::to_string(i);
  EXPECT_THROW(parse_tag_list(many, "--tags"), ProtocolError);
  EXPECT_TRUE(has_tags({"bigmem", "gpu", "site-a"}, {"bigmem", "site-a"}));
  EXPECT_FALSE(has_tags({"gpu"}, {"bigmem"}));
  EXPECT_TRUE(has_tags({}, {}));
}

TEST(SharedFarmFields, ASubmissionCarriesItsRequirementsAndCap) {
  const JobSubmission s = parse_job_submission(R"({"scene": {}, "require": ["site-a", "bigmem"], "max_workers": 8})");
  EXPECT_EQ(s.require, (std::vector<std::string>{"bigmem", "site-a"}));
  EXPECT_EQ(s.max_workers, 8);
  const JobSubmission back = parse_job_submission(nlohmann::json(s).dump());
  EXPECT_EQ(back.require, s.require);
  EXPECT_EQ(back.max_workers, 8);
  EXPECT_THROW(parse_job_submission(R"({"scene": {}, "require": ["Big Mem"]})"), ProtocolError);
  EXPECT_THROW(parse_job_submission(R"({"scene": {}, "require": "bigmem"})"), ProtocolError);
  EXPECT_THROW(parse_job_submission(R"({"scene": {}, "max_workers": -1})"), ProtocolError);
  EXPECT_EQ(parse_worker_hello(R"({"name": "w", "tags": ["gpu"]})").tags, (std::vector<std::string>{"gpu"}));
  EXPECT_THROW(parse_worker_hello(R"({"tags": ["GPU"]})"), ProtocolError);
}

TEST(SharedFarmFields, QueriesByOwnerAndOfTheAuditTrail) {
  EXPECT_EQ(parse_job_list_query("/v1/jobs?owner=ben").owner, "ben");
  EXPECT_THROW(parse_job_list_query("/v1/jobs?owner="), ProtocolError);
  JobListQuery q;
  q.owner = "ben o";
  EXPECT_EQ(parse_job_list_query("/v1/jobs" + q.to_query()).owner, "ben o");
  const AuditQuery a = parse_audit_query("/v1/audit?before=9&limit=5&user=ana");
  EXPECT_EQ(a.before.value_or(0), 9);
  EXPECT_EQ(a.limit, 5u);
  EXPECT_EQ(a.user, "ana");
  EXPECT_EQ(parse_audit_query("/v1/audit" + a.to_query()).user, "ana");
  EXPECT_THROW(parse_audit_query("/v1/audit?before=0"), ProtocolError);
  EXPECT_THROW(parse_audit_query("/v1/audit?limit=0"), ProtocolError);
  EXPECT_THROW(parse_audit_query("/v1/audit?who=ana"), ProtocolError);
}

}  // namespace
}  // namespace tessera::protocol
