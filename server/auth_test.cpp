// Bearer tokens: the check itself, which endpoint needs which token, and the coordinator enforcing it over HTTP.
#include "server/auth.h"

#include "server/api.h"
#include "server/coordinator.h"
#include "server/storage.h"
#include "server/test_coordinator.h"
#include "server/test_http_client.h"
#include "server/user_file.h"
#include "core/util/file_io.h"
#include "core/util/sha256.h"

#include <gtest/gtest.h>
#include <spdlog/sinks/ostream_sink.h>
#include <spdlog/spdlog.h>

#include <filesystem>
#include <sstream>
#include <thread>

namespace tessera::server {
namespace {

namespace fs = std::filesystem;
namespace beast = boost::beast;
using testing::Client;
using testing::Reply;
using V = http::verb;

const AccessTokens kTokens{"client-token-0123456789abcdef", "worker-token-0123456789abcdef", {}};

TEST(ConstantTimeEqual, ComparesWholeStrings) {
  EXPECT_TRUE(constant_time_equal("secret-secret-secret", "secret-secret-secret"));
  EXPECT_FALSE(constant_time_equal("secret-secret-secret", "secret-secret-secreT"));
  EXPECT_FALSE(constant_time_equal("secret-secret-secret", "secret-secret-secret "));
  EXPECT_FALSE(constant_time_equal("secret", ""));
  EXPECT_TRUE(constant_time_equal("", ""));
}

TEST(TokenProblem, RefusesShortSpacedAndControlTokens) {
  EXPECT_EQ(token_problem("0123456789abcdef"), "");
  EXPECT_NE(token_problem("short"), "");
  EXPECT_NE(token_problem("0123456789 abcdef"), "");
  EXPECT_NE(token_problem("0123456789abcdef\x01"), "");
  EXPECT_NE(token_problem(std::string(5000, 'a')), "");
}

TEST(GenerateToken, IsUsableAndFresh) {
  const std::string a = generate_token(), b = generate_token();
  EXPECT_EQ(a.size(), 48u);
  EXPECT_EQ(token_problem(a), "");
  EXPECT_NE(a, b);
}

TEST(Authorize, NoTokensConfiguredLeavesEverythingOpen) {
  for (Access a : {Access::open, Access::read, Access::submit, Access::owner, Access::admin, Access::worker, Access::either})
    EXPECT_EQ(authorize(a, "", AccessTokens{}).status, AuthDecision::allowed);
}

TEST(Authorize, ChecksSchemeTokenAndRole) {
  const std::string client = "Bearer " + kTokens.client, worker = "Bearer " + kTokens.worker;
  EXPECT_EQ(authorize(Access::open, "", kTokens).status, AuthDecision::allowed);
  EXPECT_EQ(authorize(Access::read, "", kTokens).status, AuthDecision::missing);
  EXPECT_EQ(authorize(Access::read, client, kTokens).status, AuthDecision::allowed);
  EXPECT_EQ(authorize(Access::read, worker, kTokens).status, AuthDecision::wrong_role);
  EXPECT_EQ(authorize(Access::worker, worker, kTokens).status, AuthDecision::allowed);
  EXPECT_EQ(authorize(Access::worker, client, kTokens).status, AuthDecision::wrong_role);
  EXPECT_EQ(authorize(Access::either, client, kTokens).status, AuthDecision::allowed);
  EXPECT_EQ(authorize(Access::either, worker, kTokens).status, AuthDecision::allowed);
  EXPECT_EQ(authorize(Access::either, "Bearer nope-nope-nope-nope", kTokens).status, AuthDecision::invalid);
  EXPECT_EQ(authorize(Access::read, "Basic " + kTokens.client, kTokens).status, AuthDecision::invalid);
  EXPECT_EQ(authorize(Access::read, "Bearer", kTokens).status, AuthDecision::invalid);
  EXPECT_EQ(authorize(Access::read, "Bearer   ", kTokens).status, AuthDecision::invalid);
  EXPECT_EQ(authorize(Access::read, "Bearer" + kTokens.client, kTokens).status, AuthDecision::invalid);
  // The scheme is case-insensitive and may be followed by several spaces (RFC 9110).
  EXPECT_EQ(authorize(Access::read, "bearer " + kTokens.client, kTokens).status, AuthDecision::allowed);
  EXPECT_EQ(authorize(Access::read, "BEARER  " + kTokens.client, kTokens).status, AuthDecision::allowed);
  EXPECT_EQ(authorize(Access::read, "bEaReR " + kTokens.worker, kTokens).status, AuthDecision::wrong_role);
  EXPECT_EQ(authorize(Access::read, client + "x", kTokens).status, AuthDecision::invalid);
  // A token that is a prefix of the real one is not the real one.
  EXPECT_EQ(authorize(Access::read, client.substr(0, client.size() - 1), kTokens).status, AuthDecision::invalid);
  // Reasons never repeat a token.
  for (const std::string& h : {client, worker, std::string("Bearer wrong-wrong-wrong-wrong")})
    for (Access a : {Access::read, Access::worker}) {
      const AuthDecision d = authorize(a, h, kTokens);
      EXPECT_EQ(d.reason.find(kTokens.client), std::string::npos);
      EXPECT_EQ(d.reason.find(kTokens.worker), std::string::npos);
    }
}

TEST(Authorize, OnlyTheConfiguredSideIsProtected) {
  const AccessTokens only_client{kTokens.client, "", {}};
  EXPECT_EQ(authorize(Access::worker, "", only_client).status, AuthDecision::allowed);
  EXPECT_EQ(authorize(Access::read, "", only_client).status, AuthDecision::missing);
  EXPECT_EQ(authorize(Access::either, "", only_client).status, AuthDecision::missing);
}

TEST(RouteAccess, EveryEndpointNeedsTheRightToken) {
  EXPECT_EQ(route_access(RouteId::healthz, V::get), Access::open);
  EXPECT_EQ(route_access(RouteId::metrics, V::get), Access::either);
  EXPECT_EQ(route_access(RouteId::blobs, V::post), Access::submit);
  EXPECT_EQ(route_access(RouteId::blob, V::put), Access::submit);
  EXPECT_EQ(route_access(RouteId::blob, V::head), Access::submit);
  EXPECT_EQ(route_access(RouteId::blob, V::get), Access::either);
  EXPECT_EQ(route_access(RouteId::job_spec, V::get), Access::either);
  for (RouteId r : {RouteId::jobs, RouteId::job, RouteId::job_result, RouteId::job_preview})
    EXPECT_EQ(route_access(r, V::get), Access::read);
  EXPECT_EQ(route_access(RouteId::jobs, V::post), Access::submit);
  EXPECT_EQ(route_access(RouteId::job, V::delete_), Access::owner);
  EXPECT_EQ(route_access(RouteId::worker_drain, V::post), Access::admin);
  EXPECT_EQ(route_access(RouteId::audit, V::get), Access::admin);
  EXPECT_EQ(route_access(RouteId::me, V::get), Access::either);
  for (RouteId r : {RouteId::workers, RouteId::worker_lease, RouteId::lease_heartbeat, RouteId::lease_result,
                    RouteId::lease_fail, RouteId::lease_release})
    EXPECT_EQ(route_access(r, V::post), Access::worker);
  EXPECT_EQ(route_access(RouteId::lease_state, V::get), Access::worker);
}

// A coordinator with both tokens on 127.0.0.1:0, its log captured to check that no token is ever written.
class TokenServerTest : public ::testing::Test {
 protected:
  void SetUp() override {
    sink_ = std::make_shared<spdlog::sinks::ostream_sink_mt>(log_);
    previous_ = spdlog::default_logger();
    spdlog::set_default_logger(std::make_shared<spdlog::logger>("capture", sink_));
    spdlog::set_level(spdlog::level::debug);
    CoordinatorOptions o;
    o.handler_threads = 2;
    o.limits.tokens = kTokens;
    server_ = std::make_unique<testing::RunningCoordinator>(o, "auth");
  }
  void TearDown() override {
    server_.reset();
    spdlog::set_default_logger(previous_);
    spdlog::set_level(spdlog::level::warn);
  }
  Reply call(V m, const std::string& target, const std::string& token, std::string body = {},
             const std::string& worker_secret = {}) {
    Client c(server_->endpoint());
    std::vector<std::pair<std::string, std::string>> h;
    if (!token.empty()) h.emplace_back("Authorization", "Bearer " + token);
    if (!worker_secret.empty()) h.emplace_back(protocol::kWorkerSecretHeader, worker_secret);
    return c.send(m, target, std::move(body), h);
  }

  std::ostringstream log_;
  std::shared_ptr<spdlog::sinks::ostream_sink_mt> sink_;
  std::shared_ptr<spdlog::logger> previous_;
  std::unique_ptr<testing::RunningCoordinator> server_;
};

TEST_F(TokenServerTest, EndpointsAnswer401Or403WithoutTheRightToken) {
  EXPECT_EQ(call(V::get, "/healthz", "").status, 200u);

  const Reply none = call(V::get, "/v1/jobs", "");
  EXPECT_EQ(none.status, 401u);
  EXPECT_NE(std::string(none.msg[http::field::www_authenticate]).find("Bearer"), std::string::npos);
  EXPECT_NE(none.js()["error"].get<std::string>().find("the viewer, user or admin role"), std::string::npos);
  EXPECT_EQ(call(V::get, "/v1/jobs", "not-the-token-at-all").status, 401u);
  EXPECT_EQ(call(V::get, "/v1/jobs", kTokens.worker).status, 403u);
  EXPECT_EQ(call(V::get, "/v1/jobs", kTokens.client).status, 200u);
  // Authorised but bad requests reach the endpoint's own validation.
  EXPECT_EQ(call(V::post, "/v1/jobs", kTokens.client).status, 400u);

  EXPECT_EQ(call(V::post, "/v1/workers", "", "{}").status, 401u);
  EXPECT_EQ(call(V::post, "/v1/workers", kTokens.client, "{}").status, 403u);
  const Reply reg = call(V::post, "/v1/workers", kTokens.worker, R"({"name": "w"})");
  ASSERT_EQ(reg.status, 201u) << reg.body;
  const std::string wid = reg.js()["id"].get<std::string>(), secret = reg.js()["secret"].get<std::string>();
  EXPECT_EQ(call(V::post, "/v1/workers/" + wid + "/lease", kTokens.client, {}, secret).status, 403u);
  EXPECT_EQ(call(V::post, "/v1/workers/" + wid + "/lease", kTokens.worker, {}, secret).status, 204u);
  // The worker token alone does not make a request the worker's: it needs the worker's secret too.
  EXPECT_EQ(call(V::post, "/v1/workers/" + wid + "/lease", kTokens.worker).status, 403u);
  // Looking at and draining workers is the operator's business: the client token.
  EXPECT_EQ(call(V::get, "/v1/workers", kTokens.worker).status, 403u);
  EXPECT_EQ(call(V::get, "/v1/workers", kTokens.client).status, 200u);
  EXPECT_EQ(call(V::post, "/v1/workers/" + wid + "/drain", kTokens.worker).status, 403u);
  EXPECT_EQ(call(V::post, "/v1/workers/" + wid + "/drain", kTokens.client).status, 200u);
  EXPECT_EQ(call(V::post, "/v1/workers/" + wid + "/lease", kTokens.worker, {}, secret).status, 204u);
  EXPECT_EQ(call(V::post, "/v1/workers/" + wid + "/undrain", kTokens.client).status, 200u);

  const std::string sha(64, 'a');
  EXPECT_EQ(call(V::put, "/v1/blobs/" + sha, kTokens.worker, "x").status, 403u);
  EXPECT_EQ(call(V::get, "/v1/blobs/" + sha, kTokens.worker).status, 404u);
  EXPECT_EQ(call(V::get, "/v1/blobs/" + sha, kTokens.client).status, 404u);
  EXPECT_EQ(call(V::get, "/metrics", "").status, 401u);
  EXPECT_EQ(call(V::get, "/metrics", kTokens.worker).status, 200u);
  // Unknown endpoints stay 404 and wrong methods 405 whatever the token: the route is checked first.
  EXPECT_EQ(call(V::get, "/v1/nothing", "").status, 404u);
  EXPECT_EQ(call(V::patch, "/v1/jobs", "").status, 405u);

  const std::string log = log_.str();
  EXPECT_NE(log.find("401"), std::string::npos) << "refusals are logged";
  EXPECT_EQ(log.find(kTokens.client), std::string::npos) << "the client token appeared in the log";
  EXPECT_EQ(log.find(kTokens.worker), std::string::npos) << "the worker token appeared in the log";
  EXPECT_EQ(log.find(secret), std::string::npos) << "the worker's secret appeared in the log";
}

TEST_F(TokenServerTest, UnauthorisedUploadIsRefusedBeforeItsBodyIsRead) {
  boost::asio::io_context ioc;
  beast::tcp_stream stream(ioc);
  stream.connect(server_->endpoint());
  const std::string head = "PUT /v1/blobs/" + std::string(64, 'b') +
                           " HTTP/1.1\r\nHost: 127.0.0.1\r\nContent-Length: 100000000\r\n\r\n";
  boost::asio::write(stream.socket(), boost::asio::buffer(head));
  // No body follows: the answer must come from the header alone.
  stream.expires_after(std::chrono::seconds(10));
  beast::flat_buffer buf;
  http::response<http::string_body> res;
  http::read(stream, buf, res);
  EXPECT_EQ(res.result_int(), 401u);
}

TEST(CoordinatorAccess, ListensBeyondLoopbackOnlyWithBothTokens) {
  const fs::path dir = fs::temp_directory_path() / ("tessera-auth-listen-" + random_hex(6));
  CoordinatorOptions o;
  o.host = "0.0.0.0";
  o.port = 0;
  o.data_dir = dir;
  try {
    Coordinator c(o);
    ADD_FAILURE() << "listening on 0.0.0.0 without tokens was allowed";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("without access tokens"), std::string::npos) << e.what();
  }
  o.limits.tokens.client = kTokens.client;
  EXPECT_THROW(Coordinator c(o), std::runtime_error) << "one token is not enough";
  o.limits.tokens.worker = kTokens.client;
  try {
    Coordinator c(o);
    ADD_FAILURE() << "equal client and worker tokens were accepted";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("must differ"), std::string::npos) << e.what();
  }
  o.limits.tokens.worker = "short";
  EXPECT_THROW(Coordinator c(o), std::runtime_error);
  o.limits.tokens = kTokens;
  EXPECT_NO_THROW(Coordinator c(o));
  std::error_code ec;
  fs::remove_all(dir, ec);
}

// A users file with one user of each role, in a fresh folder.
struct UsersFile {
  fs::path dir = fs::temp_directory_path() / ("tessera-users-" + random_hex(6));
  fs::path file = dir / "users.json";
  std::map<std::string, std::string> tokens;  // name -> token
  UsersFile() {
    fs::create_directories(dir);
    std::vector<User> users;
    for (const auto& [name, role] : {std::pair{"ana", protocol::Role::admin}, std::pair{"ben", protocol::Role::user},
                                     std::pair{"cy", protocol::Role::viewer}, std::pair{"wk", protocol::Role::worker}}) {
      tokens[name] = generate_token();
      users.push_back({name, role, sha256_hex(tokens[name]), 1, 0});
    }
    write_user_file(file, users);
  }
  ~UsersFile() {
    std::error_code ec;
    fs::remove_all(dir, ec);
  }
  std::string bearer(const std::string& name) { return "Bearer " + tokens.at(name); }
};

TEST(Users, EachRoleMayWhatItsAccessAdmits) {
  UsersFile u;
  const Credentials c(AccessTokens{"", "", u.file});
  using R = protocol::Role;
  const std::map<std::string, R> roles = {{"ana", R::admin}, {"ben", R::user}, {"cy", R::viewer}, {"wk", R::worker}};
  for (const auto& [name, role] : roles)
    for (Access a : {Access::read, Access::submit, Access::owner, Access::admin, Access::worker, Access::either}) {
      const AuthDecision d = c.authorize(a, u.bearer(name));
      EXPECT_EQ(d.status == AuthDecision::allowed, protocol::role_allows(role, a)) << name << " " << int(a);
      if (d.status != AuthDecision::allowed) {
        EXPECT_EQ(d.status, AuthDecision::wrong_role);
        EXPECT_NE(d.reason.find(name + " has the " + protocol::to_string(role) + " role"), std::string::npos) << d.reason;
      }
      EXPECT_EQ(d.caller.user, name);
      EXPECT_EQ(d.reason.find(u.tokens[name]), std::string::npos);
    }
  EXPECT_TRUE(protocol::role_allows(R::user, Access::owner));
  EXPECT_FALSE(protocol::acts_on_any_job(R::user));
  EXPECT_TRUE(protocol::acts_on_any_job(R::admin));
  EXPECT_EQ(c.authorize(Access::read, "Bearer " + generate_token()).status, AuthDecision::invalid);
  EXPECT_EQ(c.authorize(Access::read, "").status, AuthDecision::missing);
  // Both sides need credentials: the users file has a worker.
  EXPECT_TRUE(c.complete());
}

TEST(Users, AVerifiedCertificateNamingAUserStandsForIt) {
  UsersFile u;
  const Credentials c(AccessTokens{"", "", u.file});
  const AuthDecision d = c.authorize(Access::submit, "", "ben");
  EXPECT_EQ(d.status, AuthDecision::allowed);
  EXPECT_EQ(d.caller.user, "ben");
  EXPECT_EQ(c.authorize(Access::submit, "", "nobody").status, AuthDecision::missing);
  EXPECT_EQ(c.authorize(Access::submit, "", "cy").status, AuthDecision::wrong_role);
}

TEST(Users, AReloadRevokesARemovedUserAndKeepsTheOthers) {
  UsersFile u;
  Credentials c(AccessTokens{kTokens.client, "", u.file});
  const AuthDecision ben = c.authorize(Access::read, u.bearer("ben"));
  const AuthDecision client = c.authorize(Access::read, "Bearer " + kTokens.client);
  ASSERT_EQ(ben.status, AuthDecision::allowed);
  EXPECT_EQ(client.caller.user, "client");
  EXPECT_TRUE(c.admits(ben.credential, Access::read));
  std::vector<User> users = read_user_file(u.file);
  std::erase_if(users, [](const User& x) { return x.name == "ben"; });
  write_user_file(u.file, users);
  EXPECT_EQ(c.reload(), 3u);
  EXPECT_FALSE(c.admits(ben.credential, Access::read));
  EXPECT_EQ(c.authorize(Access::read, u.bearer("ben")).status, AuthDecision::invalid);
  EXPECT_TRUE(c.admits(client.credential, Access::read));
  EXPECT_EQ(c.authorize(Access::read, u.bearer("cy")).status, AuthDecision::allowed);
  // A broken file is refused and the users stay as they were.
  write_file_atomic(u.file, "{\"users\": [{\"name\": \"x\"}]}");
  EXPECT_THROW(c.reload(), std::runtime_error);
  EXPECT_EQ(c.authorize(Access::read, u.bearer("cy")).status, AuthDecision::allowed);
}

TEST(Users, BadFilesAreRefusedWithASentence) {
  UsersFile u;
  const auto refusal = [&](const std::string& text) {
    write_file_atomic(u.file, text);
    try {
      read_user_file(u.file);
    } catch (const std::runtime_error& e) {
      return std::string(e.what());
    }
    return std::string("accepted");
  };
  const std::string h = sha256_hex("t");
  EXPECT_NE(refusal("[]").find("expected {\"users\""), std::string::npos);
  EXPECT_NE(refusal(R"({"users": [{"name": "a", "role": "boss", "token_sha256": ")" + h + R"("}]})").find("unknown role 'boss'"),
            std::string::npos);
  EXPECT_NE(refusal(R"({"users": [{"name": "client", "role": "user", "token_sha256": ")" + h + R"("}]})").find("reserved"),
            std::string::npos);
  EXPECT_NE(refusal(R"({"users": [{"name": "a", "role": "user", "token_sha256": "abc"}]})").find("64 lowercase hex"),
            std::string::npos);
  EXPECT_NE(refusal(R"({"users": [{"name": "a", "role": "user", "token_sha256": ")" + h + R"(", "weight": 0}]})")
                .find("weight must be a positive number"),
            std::string::npos);
  EXPECT_NE(refusal(R"({"users": [{"name": "a", "role": "user", "token_sha256": ")" + h + R"("}, {"name": "a", "role": "user", "token_sha256": ")" +
                    sha256_hex("u") + R"("}]})").find("listed twice"),
            std::string::npos);
  EXPECT_NE(refusal(R"({"users": [{"name": "a", "role": "user", "token_sha256": ")" + h + R"(", "colour": 1}]})").find("unknown key 'colour'"),
            std::string::npos);
}

}  // namespace
}  // namespace tessera::server
