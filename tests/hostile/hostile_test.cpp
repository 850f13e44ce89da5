// Hostile and broken input against a live coordinator: starts the real `tessera serve` (small limits, a short read
// timeout) and a real `tessera worker`, keeps a good job rendering, sends every case of tests/hostile/cases.json over
// raw sockets and checks each answer's status and error text, then checks that the good job finished with the same
// bits as a single-process render, that a second good job does too, and that /healthz still answers.
// docs/hostile-inputs.md is generated from the same case list (TESSERA_UPDATE_HOSTILE_DOC=1 rewrites it) and a test
// fails when the two differ.
#include "core/image/image.h"
#include "core/util/sha256.h"
#include "worker/child_process.h"

#include <boost/asio/buffer.hpp>
#include <boost/beast/http.hpp>
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <arpa/inet.h>
#include <fcntl.h>
#include <netinet/in.h>
#include <poll.h>
#include <signal.h>
#include <sys/socket.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cerrno>
#include <chrono>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <map>
#include <optional>
#include <random>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

namespace tessera {
namespace {

namespace fs = std::filesystem;
namespace http = boost::beast::http;
using json = nlohmann::json;

const fs::path kSource = TESSERA_SOURCE_DIR;
const fs::path kCases = kSource / "tests/hostile/cases.json";
const fs::path kDoc = kSource / "docs/hostile-inputs.md";

// The coordinator's read timeout (whole request) in this test, and the bound within which a slow or idle client
// must see the server close its connection: the timeout plus a slack for scheduling on a loaded machine. A server
// that ignored the flag would close only after its default 30 s and fail the bound.
constexpr int kReadTimeoutSeconds = 1;
constexpr double kCloseBoundSeconds = kReadTimeoutSeconds + 9.0;
// The client's own socket timeout: three times the bound, so that it can never be mistaken for a server close
// (the test also tells them apart by how the socket call ended).
constexpr int kClientTimeoutSeconds = 30;
// The most any case may raise the coordinator's peak resident memory (VmHWM), in kB.
constexpr uint64_t kCaseMemoryBoundKb = 64 * 1024;
static_assert(kClientTimeoutSeconds >= 3 * kCloseBoundSeconds);

// The limits the coordinator under test runs with (the case list's texts quote them).
const std::vector<std::string> kServeLimits = {
    "--read-timeout-seconds", std::to_string(kReadTimeoutSeconds), "--max-connections", "16", "--max-queued-jobs", "4",
    "--max-json-bytes",       "65536",  "--max-blob-bytes",  "1048576",  "--max-result-bytes", "4194304",
    "--max-header-bytes",     "8192",   "--max-job-pixels",  "1048576",  "--max-job-samples",  "1e8",
    "--max-event-streams",    "4",      "--max-asset-pixels", "262144",   "--max-mesh-triangles", "1000",
    "--webhook-allow",        "http://127.0.0.1:9/hooks/"};

std::string slurp(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  std::ostringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

void spit(const fs::path& p, const std::string& bytes) {
  std::ofstream out(p, std::ios::binary | std::ios::trunc);
  out.write(bytes.data(), std::streamsize(bytes.size()));
}

// ---- processes

// A child process (worker/child_process.h) with stdout and stderr appended to a log file; stopped with SIGTERM (then
// SIGKILL after 10 s) when destroyed.
class Process {
 public:
  Process(const std::vector<std::string>& args, const fs::path& log) : child_{worker::spawn_child(args, args[0], log)} {}
  ~Process() { stop(); }
  Process(const Process&) = delete;
  Process& operator=(const Process&) = delete;

  /// True while the process has not exited.
  bool alive() { return !worker::child_exited(child_[0]); }
  /// SIGTERM, up to 10 s to exit, then SIGKILL.
  void stop() { worker::stop_children(child_, std::chrono::seconds(10)); }
  /// The process id.
  pid_t pid() const { return child_[0].pid; }

 private:
  std::vector<worker::ChildProcess> child_;  // one element: the form stop_children takes
};

// A line of /proc/PID/status in kB (VmRSS: resident now, VmHWM: its peak since the last reset_peak_rss), 0 when
// unreadable.
uint64_t status_kb(pid_t pid, const std::string& key) {
  std::ifstream in("/proc/" + std::to_string(pid) + "/status");
  for (std::string line; std::getline(in, line);)
    if (line.rfind(key + ":", 0) == 0) return std::stoull(line.substr(key.size() + 1));
  return 0;
}

// Resets the process's peak resident size (VmHWM) to its current one; false when the kernel refuses.
bool reset_peak_rss(pid_t pid) {
  std::ofstream out("/proc/" + std::to_string(pid) + "/clear_refs");
  out << "5";
  out.flush();
  return bool(out);
}

// Runs a command to completion with its output in a fresh log; returns its exit status (-1 when it did not exit
// normally).
int run(const std::vector<std::string>& args, const fs::path& log) {
  std::error_code ec;
  fs::remove(log, ec);  // spawn_child appends
  worker::ChildProcess c = worker::spawn_child(args, args[0], log);
  while (!worker::child_exited(c)) std::this_thread::sleep_for(std::chrono::milliseconds(20));
  return WIFEXITED(c.exit_status) ? WEXITSTATUS(c.exit_status) : -1;
}

// ---- raw HTTP over POSIX sockets (so a test can trickle, stall, or send bytes no client library would)

// One answer as the client saw it; status 0 means the connection closed (or timed out) without an answer.
struct Reply {
  unsigned status = 0;
  std::string body;
  std::map<std::string, std::string> headers;
  std::string error() const {
    const json j = json::parse(body, nullptr, false);
    return j.is_object() && j.contains("error") && j["error"].is_string() ? j["error"].get<std::string>() : std::string();
  }
};

// How a socket call that found no more data (or could not send) ended.
enum class End {
  open,            ///< Not ended.
  server_closed,   ///< The peer closed (EOF) or reset the connection.
  client_timeout,  ///< The client's own socket timeout expired.
  error,           ///< Any other failure.
};

End end_of(ssize_t n, int err) {
  if (n == 0) return End::server_closed;
  if (err == ECONNRESET || err == EPIPE) return End::server_closed;
  if (err == EAGAIN || err == EWOULDBLOCK) return End::client_timeout;
  return End::error;
}

// A connected loopback socket with send/receive timeouts (so a broken server fails the test, never hangs it).
class Conn {
 public:
  explicit Conn(int port) {
    fd_ = ::socket(AF_INET, SOCK_STREAM, 0);
    timeval tv{kClientTimeoutSeconds, 0};
    setsockopt(fd_, SOL_SOCKET, SO_RCVTIMEO, &tv, sizeof tv);
    setsockopt(fd_, SOL_SOCKET, SO_SNDTIMEO, &tv, sizeof tv);
    sockaddr_in a{};
    a.sin_family = AF_INET;
    a.sin_port = htons(uint16_t(port));
    a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    ok_ = ::connect(fd_, reinterpret_cast<sockaddr*>(&a), sizeof a) == 0;
  }
  ~Conn() {
    if (fd_ >= 0) ::close(fd_);
  }
  Conn(const Conn&) = delete;
  Conn& operator=(const Conn&) = delete;

  bool ok() const { return ok_; }
  /// How the connection ended, as seen by the last call that found its end (End::open until then).
  End end() const { return end_; }
  /// Sends everything; false when the connection is gone (see end()).
  bool send(std::string_view bytes) {
    while (!bytes.empty()) {
      const ssize_t n = ::send(fd_, bytes.data(), bytes.size(), MSG_NOSIGNAL);
      if (n <= 0) {
        end_ = end_of(n, errno);
        return false;
      }
      bytes.remove_prefix(size_t(n));
    }
    return true;
  }
  /// True when the connection has ended (see end()); reads nothing that is not an end.
  bool ended() {
    pollfd p{fd_, POLLIN, 0};
    if (::poll(&p, 1, 0) <= 0) return false;
    char c;
    const ssize_t n = ::recv(fd_, &c, 1, MSG_PEEK | MSG_DONTWAIT);
    if (n > 0) return false;
    end_ = end_of(n, errno);
    return true;
  }
  /// Reads a response's status line only (0 if the connection ends first), e.g. of a stream that never ends.
  unsigned read_status() {
    char buf[4096];
    while (pending_.find("\r\n") == std::string::npos) {
      const ssize_t n = ::recv(fd_, buf, sizeof buf, 0);
      if (n <= 0) {
        end_ = end_of(n, errno);
        return 0;
      }
      pending_.append(buf, size_t(n));
    }
    return pending_.starts_with("HTTP/1.1 ") && pending_.size() >= 12 ? unsigned(std::stoi(pending_.substr(9, 3))) : 0;
  }
  /// Reads one response (status 0 if the connection ends first).
  Reply read(bool head = false) {
    http::response_parser<http::string_body> parser;
    parser.body_limit(std::uint64_t(1) << 30);
    parser.eager(true);
    if (head) parser.skip(true);
    Reply r;
    bool got_bytes = !pending_.empty();
    char buf[65536];
    for (;;) {
      boost::beast::error_code ec;
      while (!pending_.empty() && !parser.is_done()) {
        const size_t used = parser.put(boost::asio::buffer(pending_), ec);
        pending_.erase(0, used);
        if (ec == http::error::need_more) {
          ec = {};
          break;
        }
        if (ec) return r;
        if (used == 0) break;
      }
      if (parser.is_done()) break;
      const ssize_t n = ::recv(fd_, buf, sizeof buf, 0);
      if (n <= 0) {
        end_ = end_of(n, errno);
        if (!got_bytes) return r;  // closed before answering (Beast would complete an empty message here)
        parser.put_eof(ec);
        if (ec || !parser.is_done()) return r;
        break;
      }
      pending_.append(buf, size_t(n));
      got_bytes = true;
    }
    const auto& msg = parser.get();
    r.status = msg.result_int();
    r.body = msg.body();
    for (const auto& f : msg) r.headers[std::string(f.name_string())] = std::string(f.value());
    return r;
  }

 private:
  int fd_ = -1;
  bool ok_ = false;
  End end_ = End::open;
  std::string pending_;
};

// "METHOD TARGET HTTP/1.1" with Host, the given headers, Content-Length and the body.
std::string request_bytes(const std::string& method, const std::string& target, const std::string& body,
                          const std::map<std::string, std::string>& headers = {}, bool keep_alive = false,
                          std::optional<uint64_t> content_length = std::nullopt) {
  std::string s = method + " " + target + " HTTP/1.1\r\nHost: 127.0.0.1\r\n";
  for (const auto& [k, v] : headers) s += k + ": " + v + "\r\n";
  s += "Content-Length: " + std::to_string(content_length ? *content_length : body.size()) + "\r\n";
  if (!keep_alive) s += "Connection: close\r\n";
  return s + "\r\n" + body;
}

// ---- the case list

// Replaces \xHH escapes (as written in cases.json for bytes JSON cannot carry) with the bytes.
std::string unescape_bytes(const std::string& s) {
  std::string out;
  for (size_t i = 0; i < s.size(); ++i) {
    if (s[i] == '\\' && i + 3 < s.size() && s[i + 1] == 'x') {
      out += char(std::stoi(s.substr(i + 2, 2), nullptr, 16));
      i += 3;
    } else {
      out += s[i];
    }
  }
  return out;
}

std::string substitute(std::string s, const std::map<std::string, std::string>& vars) {
  for (const auto& [k, v] : vars) {
    const std::string key = "${" + k + "}";
    for (size_t at = s.find(key); at != std::string::npos; at = s.find(key, at + v.size())) s.replace(at, key.size(), v);
  }
  return s;
}

json load_cases() { return json::parse(slurp(kCases))["cases"]; }

// The markdown table of docs/hostile-inputs.md, generated from the case list.
std::string doc_table(const json& cases) {
  auto cell = [](std::string s) {
    for (size_t at = s.find('|'); at != std::string::npos; at = s.find('|', at + 2)) s.replace(at, 1, "\\|");
    return s;
  };
  std::string t = "| # | case | input | response | error text (contains) |\n|---|---|---|---|---|\n";
  int n = 0;
  for (const json& c : cases) {
    const int status = c["status"].get<int>();
    const std::string kind = c.value("kind", "");
    std::string response = std::to_string(status);
    if (kind == "submit_symlink") response = "`tessera submit` exits " + std::to_string(status) + ", nothing uploaded";
    else if (status == 0) response = "connection closed after the read timeout, no answer";
    const std::string error = c["error"].get<std::string>();
    t += "| " + std::to_string(++n) + " | `" + c["name"].get<std::string>() + "` | " + cell(c["input"].get<std::string>()) +
         " | " + response + " | " + (error.empty() ? std::string("(no body)") : "`" + cell(error) + "`") + " |\n";
  }
  return t;
}

constexpr const char* kBegin = "<!-- cases: begin (generated from tests/hostile/cases.json) -->\n";
constexpr const char* kEnd = "<!-- cases: end -->\n";

TEST(HostileDoc, TableMatchesTheCaseList) {
  const json cases = load_cases();
  ASSERT_GE(cases.size(), 50u);
  std::string doc = slurp(kDoc);
  const size_t b = doc.find(kBegin), e = doc.find(kEnd);
  ASSERT_NE(b, std::string::npos) << kDoc << " has no begin marker";
  ASSERT_NE(e, std::string::npos) << kDoc << " has no end marker";
  const std::string want = doc_table(cases);
  const std::string have = doc.substr(b + std::strlen(kBegin), e - b - std::strlen(kBegin));
  if (have != want && std::getenv("TESSERA_UPDATE_HOSTILE_DOC")) {
    doc.replace(b + std::strlen(kBegin), have.size(), want);
    spit(kDoc, doc);
    return;
  }
  EXPECT_EQ(have, want) << kDoc << " differs from " << kCases
                        << "; run hostile_tests with TESSERA_UPDATE_HOSTILE_DOC=1 to regenerate it";
}

// ---- the live farm

class HostileFarm : public ::testing::Test {
 protected:
  void SetUp() override {
    work_ = fs::temp_directory_path() / ("tessera-hostile-" + std::to_string(::getpid()));
    fs::remove_all(work_);
    fs::create_directories(work_);
    std::vector<std::string> args = {TESSERA_BINARY, "serve", "--listen", "127.0.0.1:0", "--ready-file",
                                     (work_ / "ready").string(), "--data", (work_ / "data").string(), "--threads", "2"};
    args.insert(args.end(), kServeLimits.begin(), kServeLimits.end());
    serve_ = std::make_unique<Process>(args, work_ / "serve.log");
    for (int i = 0; i < 600 && port_ == 0; ++i) {
      const std::string ready = slurp(work_ / "ready");
      if (const size_t colon = ready.rfind(':'); colon != std::string::npos && ready.back() == '\n')
        port_ = std::stoi(ready.substr(colon + 1));
      else
        std::this_thread::sleep_for(std::chrono::milliseconds(50));
    }
    ASSERT_NE(port_, 0) << "the coordinator did not become ready:\n" << slurp(work_ / "serve.log");
    url_ = "http://127.0.0.1:" + std::to_string(port_);
    // The worker renders the good job's first tile, then holds before its second (fail point worker.render, in the
    // test binary) until the file `release_` exists: the good job is running, with a tile done and one leased,
    // through every case, whatever the machine's speed.
    ::setenv("TESSERA_FAIL_POINTS", ("worker.render=1*off->pause(" + release_.string() + ")").c_str(), 1);
    worker_ = std::make_unique<Process>(std::vector<std::string>{TESSERA_FAILPOINTS_BINARY, "worker", "--coordinator", url_,
                                                                 "--threads", "1", "--cache", (work_ / "cache").string(),
                                                                 "--name", "good"},
                                        work_ / "worker.log");
    ::unsetenv("TESSERA_FAIL_POINTS");
  }

  void TearDown() override {
    std::ofstream(release_) << "go";  // a held worker stops at once
    worker_.reset();
    fs::remove(release_);
    serve_.reset();
    if (!HasFailure()) fs::remove_all(work_);
    else std::fprintf(stderr, "logs kept in %s\n", work_.c_str());
  }

  Reply call(const std::string& method, const std::string& target, const std::string& body = {},
             const std::map<std::string, std::string>& headers = {}) {
    Conn c(port_);
    if (!c.ok() || !c.send(request_bytes(method, target, body, headers))) return {};
    return c.read(method == "HEAD");
  }

  std::string put_blob(const std::string& bytes) {
    const std::string h = sha256_hex(bytes);
    const Reply r = call("PUT", "/v1/blobs/" + h, bytes);
    EXPECT_TRUE(r.status == 201 || r.status == 200) << r.status << " " << r.body;
    return h;
  }

  // Polls a job until it ends (bounded: a job that never ends fails the test instead of hanging it).
  json wait_job(const std::string& id) {
    json last;
    for (int i = 0; i < 3000; ++i) {
      const Reply r = call("GET", "/v1/jobs/" + id);
      last = json::parse(r.body, nullptr, false);
      if (r.status != 200) break;
      const std::string st = last.value("state", "");
      if (st != "queued" && st != "running") break;
      std::this_thread::sleep_for(std::chrono::milliseconds(100));
    }
    return last;
  }

  // The good scene: the course's textured Cornell box (OBJ meshes and an EXR texture), small.
  json good_scene(int spp) {
    json scene = json::parse(slurp(fs::path(TESSERA_COURSE_DIR) / "cbox_refract_textured.json"));
    scene["film"]["resolution"] = {128, 96};
    scene["integrator"]["spp"] = spp;
    return scene;
  }

  void check_case(const json& c, const std::map<std::string, std::string>& vars, const json& bases);

  // The good job's body (the good scene at `spp` with its assets uploaded, seed 11, tiles of `tile_size` pixels,
  // priority 10), after rendering it on this machine into ref.exr, the reference it must match.
  json good_job(int spp = 128, int tile_size = 8) {
    const fs::path scene_dir = work_ / "good";
    fs::create_directories(scene_dir);
    fs::copy(fs::path(TESSERA_COURSE_DIR) / "assets", scene_dir / "assets", fs::copy_options::recursive);
    const json scene = good_scene(spp);
    spit(scene_dir / "scene.json", scene.dump());
    EXPECT_EQ(run({TESSERA_BINARY, "render", (scene_dir / "scene.json").string(), "-o", (work_ / "ref.exr").string(),
                   "-q", "--seed", "11"},
                  work_ / "render.log"),
              0)
        << slurp(work_ / "render.log");
    json good = {{"scene", scene}, {"assets", json::object()}, {"seed", 11}, {"tile_size", tile_size},
                 {"priority", 10}, {"name", "good"}};
    for (const auto& entry : fs::recursive_directory_iterator(scene_dir / "assets")) {
      if (!entry.is_regular_file()) continue;
      good["assets"][fs::relative(entry.path(), scene_dir).generic_string()] = put_blob(slurp(entry.path()));
    }
    return good;
  }

  // Submits `job` and waits until the good worker has rendered a tile of it and holds its second; returns the job's
  // id, or "" (with a failure recorded) when it did not get there.
  std::string submit_and_hold(const json& job) {
    const Reply r = call("POST", "/v1/jobs", job.dump());
    EXPECT_EQ(r.status, 201u) << r.body;
    if (r.status != 201) return {};
    const std::string id = json::parse(r.body)["id"].get<std::string>();
    const json start = wait_until_held(id);
    EXPECT_EQ(start.value("state", ""), "running") << start.dump();
    EXPECT_EQ(start["tiles"].value("leased", 0), 1) << start.dump();
    return start.value("state", "") == "running" && start["tiles"].value("leased", 0) == 1 ? id : std::string();
  }

  // Waits (300 s at most) until the worker holds the job's second tile at its fail point, with the first one done
  // (its upload may still be on its way when the hold begins); returns the job as it then is.
  json wait_until_held(const std::string& job) {
    json start;
    const auto held_with_one_done = [&] {
      start = json::parse(call("GET", "/v1/jobs/" + job).body, nullptr, false);
      return slurp(work_ / "worker.log").find("fail point worker.render: hit") != std::string::npos &&
             start.is_object() && start["tiles"].value("done", 0) >= 1 && start["tiles"].value("leased", 0) == 1;
    };
    for (int i = 0; i < 3000 && !held_with_one_done(); ++i) std::this_thread::sleep_for(std::chrono::milliseconds(100));
    EXPECT_NE(slurp(work_ / "worker.log").find("fail point worker.render: hit"), std::string::npos)
        << "the worker never held its second tile:\n" << slurp(work_ / "worker.log");
    return start;
  }

  // Waits for the job to end and checks that it is done with the reference's bits.
  void expect_done_like_reference(const std::string& id) {
    const ExrImage ref = read_exr(work_ / "ref.exr");
    const json end = wait_job(id);
    ASSERT_EQ(end.value("state", ""), "done") << end.dump() << "\n" << slurp(work_ / "worker.log");
    const Reply res = call("GET", "/v1/jobs/" + id + "/result.exr");
    ASSERT_EQ(res.status, 200u);
    spit(work_ / (id + ".exr"), res.body);
    const ExrImage got = read_exr(work_ / (id + ".exr"));
    ASSERT_EQ(got.pixels.width, ref.pixels.width);
    ASSERT_EQ(got.pixels.height, ref.pixels.height);
    EXPECT_EQ(std::memcmp(got.pixels.rgb.data(), ref.pixels.rgb.data(), ref.pixels.rgb.size() * sizeof(float)), 0)
        << id << " differs from the single-process render";
  }

  fs::path work_;
  int port_ = 0;
  std::string url_;
  std::unique_ptr<Process> serve_, worker_;
  fs::path release_ = fs::temp_directory_path() / ("tessera-hostile-release-" + std::to_string(::getpid()));
};

// Sends one case and checks its answer.
void HostileFarm::check_case(const json& c, const std::map<std::string, std::string>& vars, const json& bases) {
  const std::string name = c["name"].get<std::string>(), kind = c.value("kind", "request"),
                    want_error = c["error"].get<std::string>();
  const unsigned want = c["status"].get<unsigned>();
  SCOPED_TRACE("case " + name + ": " + c["input"].get<std::string>());
  Reply r;
  if (kind == "request") {
    std::string bytes;
    if (c.contains("raw")) {
      bytes = c["raw"].get<std::string>();
    } else if (c.contains("raw_repeat")) {
      const json& g = c["raw_repeat"];
      bytes = g["prefix"].get<std::string>();
      for (int i = 0, n = g["count"].get<int>(); i < n; ++i) bytes += g["unit"].get<std::string>();
      bytes += g.value("suffix", "");
    } else {
      std::string body;
      if (c.contains("base")) {
        json b = bases[c["base"].get<std::string>()];
        b.merge_patch(c["patch"]);
        body = b.dump();
        if (c.contains("body_replace")) {
          const std::string from = c["body_replace"][0].get<std::string>(), to = c["body_replace"][1].get<std::string>();
          const size_t at = body.find(from);
          ASSERT_NE(at, std::string::npos);
          body.replace(at, from.size(), to);
        }
      } else if (c.contains("body_repeat")) {
        const json& g = c["body_repeat"];
        const int n = g["count"].get<int>();
        body = g.value("prefix", "");
        for (int i = 0; i < n; ++i) body += g["unit"].get<std::string>();
        body += g.value("suffix", "");
        for (int i = 0; i < n && g.contains("close"); ++i) body += g["close"].get<std::string>();
        body += g.value("end", "");
      } else {
        body = c.value("body", "");
      }
      body = substitute(body, vars);
      if (c.value("body_escapes", false)) body = unescape_bytes(body);
      std::string target = substitute(c["target"].get<std::string>(), vars);
      if (c.value("target_escapes", false)) target = unescape_bytes(target);
      std::map<std::string, std::string> headers;
      const json hs = c.value("headers", json::object());
      for (auto it = hs.begin(); it != hs.end(); ++it) headers[it.key()] = substitute(it.value().get<std::string>(), vars);
      std::optional<uint64_t> length;
      if (c.contains("content_length")) length = c["content_length"].get<uint64_t>();
      bytes = request_bytes(c["method"].get<std::string>(), target, body, headers, false, length);
    }
    Conn conn(port_);
    ASSERT_TRUE(conn.ok());
    conn.send(bytes);  // the server may answer (413, 431) and close before taking all of it
    r = conn.read(c.value("method", "") == "HEAD");
  } else if (kind == "chunked_flood") {
    Conn conn(port_);
    ASSERT_TRUE(conn.ok());
    conn.send("POST /v1/jobs HTTP/1.1\r\nHost: 127.0.0.1\r\nTransfer-Encoding: chunked\r\n\r\n");
    const std::string chunk = "4000\r\n" + std::string(0x4000, ' ') + "\r\n";
    for (int i = 0; i < 64 && conn.send(chunk); ++i) {
    }
    r = conn.read();
  } else if (kind == "slowloris" || kind == "idle") {
    Conn conn(port_);
    ASSERT_TRUE(conn.ok());
    const auto t0 = std::chrono::steady_clock::now();
    auto elapsed = [&] { return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count(); };
    if (kind == "idle") {
      r = conn.read();  // blocks until the server closes (or the client's own socket timeout)
      EXPECT_EQ(r.status, 0u) << "the server answered a request never sent";
    } else {
      const bool body = c["stage"].get<std::string>() == "body";
      conn.send(body ? "POST /v1/jobs HTTP/1.1\r\nHost: 127.0.0.1\r\nContent-Length: 100000\r\n\r\n"
                     : "GET /healthz HTTP/1.1\r\nHost: 127.0.0.1\r\nX-Slow: ");
      // One byte every 100 ms, never finishing the request, until the connection ends or the client gives up.
      while (elapsed() < kClientTimeoutSeconds) {
        std::this_thread::sleep_for(std::chrono::milliseconds(100));
        if (conn.ended() || !conn.send("a")) break;
      }
    }
    const double secs = elapsed();
    std::printf("  %s: ended=%d after %.2f s (read timeout %d s, bound %.0f s)\n", name.c_str(), int(conn.end()), secs,
                kReadTimeoutSeconds, kCloseBoundSeconds);
    EXPECT_EQ(conn.end(), End::server_closed) << "the server did not close the connection (end " << int(conn.end()) << ")";
    // Not before the timeout (the client's clock starts before the server accepts, so never later than the server's),
    // and within the bound.
    EXPECT_GE(secs, kReadTimeoutSeconds * 0.95) << "closed before the read timeout";
    EXPECT_LE(secs, kCloseBoundSeconds) << "not closed within the read timeout's bound";
    r = Reply{};
  } else if (kind == "connections") {
    // Open keep-alive connections one by one (each answers /healthz) until the server refuses one.
    std::vector<std::unique_ptr<Conn>> open;
    for (int i = 0; i < 40; ++i) {
      auto conn = std::make_unique<Conn>(port_);
      ASSERT_TRUE(conn->ok());
      conn->send(request_bytes("GET", "/healthz", "", {}, true));
      r = conn->read();
      open.push_back(std::move(conn));
      if (r.status != 200) break;
    }
    EXPECT_LE(open.size(), 17u) << "more connections than the limit were served";
    EXPECT_EQ(r.headers.count("Retry-After"), 1u);
    // Freed slots serve again once the server has seen the clients close.
    const Reply before = r;
    open.clear();
    unsigned after = 0;
    for (int i = 0; i < 100 && after != 200; ++i) {
      after = call("GET", "/healthz").status;
      if (after != 200) std::this_thread::sleep_for(std::chrono::milliseconds(100));
    }
    EXPECT_EQ(after, 200u) << "closing connections did not free their slots";
    r = before;
  } else if (kind == "anonymous_flood") {
    // One address opens connections that never send a byte, more than there are slots; each new one displaces the
    // oldest idle one, and a client arriving after them is still answered.
    std::vector<std::unique_ptr<Conn>> idle;
    for (int i = 0; i < 24; ++i) {
      idle.push_back(std::make_unique<Conn>(port_));
      ASSERT_TRUE(idle.back()->ok());
    }
    Conn conn(port_);
    ASSERT_TRUE(conn.ok());
    conn.send(request_bytes("GET", "/healthz", "", {}));
    r = conn.read();
  } else if (kind == "event_streams") {
    // Event streams whose clients never read a byte, until the server refuses one; the coordinator goes on.
    std::vector<std::unique_ptr<Conn>> open;
    for (int i = 0; i < 10; ++i) {
      auto conn = std::make_unique<Conn>(port_);
      ASSERT_TRUE(conn->ok());
      conn->send(request_bytes("GET", "/v1/events", "", {}, true));
      if (i < 4) {
        // Its status line first: requests on different connections are answered in any order, so the next stream
        // is opened only once this one holds its slot (else the 5th could take the slot and the 4th get the 503).
        ASSERT_EQ(conn->read_status(), 200u) << "event stream " << i + 1 << " of 4 was refused";
        open.push_back(std::move(conn));  // never read beyond the status line
        continue;
      }
      r = conn->read();
      break;
    }
    EXPECT_EQ(call("GET", "/healthz").status, 200u) << "never-reading streams held up the coordinator";
    EXPECT_EQ(r.headers.count("Retry-After"), 1u);
    // Closing them frees their streams.
    const Reply before = r;
    open.clear();
    unsigned after = 0;
    for (int i = 0; i < 100 && after != 200; ++i) {
      Conn again(port_);
      again.send(request_bytes("GET", "/v1/events", "", {}, true));
      after = again.read_status();
      if (after != 200) std::this_thread::sleep_for(std::chrono::milliseconds(100));
    }
    EXPECT_EQ(after, 200u) << "closing event streams did not free them";
    r = before;
  } else if (kind == "queue_full") {
    std::vector<std::string> fillers;
    for (int i = 0; i < 10; ++i) {
      r = call("POST", "/v1/jobs", bases["sphere"].dump());
      if (r.status != 201) break;
      fillers.push_back(json::parse(r.body)["id"].get<std::string>());
    }
    EXPECT_EQ(r.headers.count("Retry-After"), 1u);
    for (const auto& id : fillers) EXPECT_EQ(call("DELETE", "/v1/jobs/" + id).status, 200u);
    // A submission is accepted again once the queue has room.
    const Reply again = call("POST", "/v1/jobs", bases["sphere"].dump());
    EXPECT_EQ(again.status, 201u) << again.body;
    if (again.status == 201) call("DELETE", "/v1/jobs/" + json::parse(again.body)["id"].get<std::string>());
  } else if (kind == "submit_symlink") {
    const fs::path dir = work_ / "symlink";
    fs::create_directories(dir / "scene/assets");
    fs::create_directories(dir / "outside");
    spit(dir / "outside/quad.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n");
    fs::create_symlink("../../outside/quad.obj", dir / "scene/assets/link.obj");
    json scene = bases["sphere"]["scene"];
    scene["objects"] = json::array({{{"type", "mesh"}, {"path", "assets/link.obj"}, {"material_name", "m"}}});
    spit(dir / "scene/scene.json", scene.dump());
    const int rc = run({TESSERA_BINARY, "submit", (dir / "scene/scene.json").string(), "--coordinator", url_, "-q"},
                       dir / "submit.log");
    const std::string log = slurp(dir / "submit.log");
    EXPECT_EQ(rc, int(want)) << log;
    EXPECT_NE(log.find(want_error), std::string::npos) << log;
    return;
  } else {
    FAIL() << "unknown kind " << kind;
  }
  EXPECT_EQ(r.status, want) << r.body;
  if (!want_error.empty()) {
    EXPECT_NE(r.error().find(want_error), std::string::npos) << r.body;
  }
  if (r.status >= 400 && c.value("method", "") != "HEAD") {
    EXPECT_FALSE(r.error().empty()) << "no JSON error body: " << r.body;
  }
}

TEST_F(HostileFarm, EveryCaseGetsItsAnswerAndTheGoodJobStillRendersRight) {
  // The good job (and the reference it must match bit for bit).
  json good = good_job();
  Reply r = call("POST", "/v1/jobs", good.dump());
  ASSERT_EQ(r.status, 201u) << r.body;
  const std::string good_job = json::parse(r.body)["id"].get<std::string>();

  // Blobs and jobs the cases refer to.
  std::map<std::string, std::string> vars;
  vars["GOOD_JOB"] = good_job;
  vars["OBJ_SHA"] = put_blob("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n");
  vars["BAD_OBJ_SHA"] = put_blob("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 4\n");
  vars["INF_OBJ_SHA"] = put_blob("v 1e39 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n");
  Image img = Image::make(16, 16);
  for (int y = 0; y < 16; ++y)
    for (int x = 0; x < 16; ++x) img.set(x, y, Vec3(float(x) / 16.f, float(y) / 16.f, 0.5f));
  write_exr(work_ / "tex.exr", img);
  const std::string exr = slurp(work_ / "tex.exr");
  vars["EXR_SHA"] = put_blob(exr);
  vars["TRUNCATED_EXR_SHA"] = put_blob(exr.substr(0, exr.size() / 2));
  img.set(3, 3, Vec3(std::numeric_limits<float>::quiet_NaN(), 0.f, 0.f));
  write_exr(work_ / "nan.exr", img);
  vars["NAN_EXR_SHA"] = put_blob(slurp(work_ / "nan.exr"));
  // A texture whose comment claims 1.9 GB in a file of a few hundred bytes (OpenEXR would allocate the claim).
  ExrWriteOptions commented;
  commented.metadata = {{"comment", "seed"}};
  write_exr(work_ / "claims.exr", img, commented);
  std::string claims = slurp(work_ / "claims.exr");
  const std::string comment_key("comment\0string\0", 15);
  const size_t comment_at = claims.find(comment_key);
  EXPECT_NE(comment_at, std::string::npos);
  const int32_t huge_size = 1979711492;  // little-endian on the test machines
  if (comment_at != std::string::npos) std::memcpy(claims.data() + comment_at + comment_key.size(), &huge_size, 4);
  vars["HUGE_ATTRIBUTE_EXR_SHA"] = put_blob(claims);
  std::string garbage(4096, '\0');
  std::mt19937 rng(5);
  for (char& ch : garbage) ch = char(rng() & 0xff);
  vars["GARBAGE_EXR_SHA"] = put_blob(garbage);
  // A 16x16 texture whose header claims a 16384 x 16384 data window (3 GiB of float RGB), over --max-asset-pixels.
  std::string huge_window = slurp(work_ / "tex.exr");
  const std::string window_key("dataWindow\0box2i\0", 17);
  const size_t window_at = huge_window.find(window_key);
  EXPECT_NE(window_at, std::string::npos);
  const int32_t window[4] = {0, 0, 16383, 16383};  // little-endian on the test machines
  if (window_at != std::string::npos) std::memcpy(huge_window.data() + window_at + window_key.size() + 4, window, 16);
  vars["HUGE_WINDOW_EXR_SHA"] = put_blob(huge_window);
  // An OBJ of 1001 triangles, over --max-mesh-triangles.
  std::string many_faces = "v 0 0 0\nv 1 0 0\nv 0 1 0\n";
  for (int i = 0; i < 1001; ++i) many_faces += "f 1 2 3\n";
  vars["MANY_FACES_OBJ_SHA"] = put_blob(many_faces);
  vars["MISSING_SHA"] = sha256_hex("never uploaded");
  vars["A_SHA"] = sha256_hex("a");
  vars["A_SHA_UPPER"] = vars["A_SHA"];
  for (char& ch : vars["A_SHA_UPPER"]) ch = char(std::toupper(static_cast<unsigned char>(ch)));

  const json sphere_scene = {
      {"film", {{"resolution", {8, 8}}}},
      {"integrator", {{"spp", 1}, {"point_light_position", {0, 3, 3}}, {"point_light_flux", {40, 40, 40}}}},
      {"camera", {{"position", {0, 0.3, 4}}, {"look_at", {0, 0, 0}}, {"fov", 45}}},
      {"textures", {{"c", {{"type", "constant"}, {"color", {0.8, 0.7, 0.6}}}}}},
      {"materials", {{"m", {{"type", "diffuse"}, {"texture_name", "c"}}}}},
      {"objects", {{{"type", "sphere"}, {"center", {0, 0, 0}}, {"radius", 0.7}, {"material_name", "m"}}}}};
  const json bases = {{"sphere", {{"scene", sphere_scene}, {"seed", 1}, {"tile_size", 8}, {"priority", -1000}}}};
  r = call("POST", "/v1/jobs", bases["sphere"].dump());
  ASSERT_EQ(r.status, 201u) << r.body;
  vars["CANCELLED_JOB"] = json::parse(r.body)["id"].get<std::string>();
  ASSERT_EQ(call("DELETE", "/v1/jobs/" + vars["CANCELLED_JOB"]).status, 200u);

  // Every case, while the good job renders: its first tile done and the worker held on its second.
  const json cases = load_cases();
  const json start = wait_until_held(good_job);
  const json workers = json::parse(call("GET", "/v1/workers").body)["workers"];
  ASSERT_EQ(workers.size(), 1u);
  vars["GOOD_WORKER"] = workers[0]["id"].get<std::string>();
  ASSERT_EQ(start.value("state", ""), "running") << start.dump();
  ASSERT_GE(start["tiles"].value("done", 0), 1) << start.dump();
  ASSERT_EQ(start["tiles"].value("leased", 0), 1) << start.dump();
  const auto t0 = std::chrono::steady_clock::now();
  // No case may raise the coordinator's peak memory more than kCaseMemoryBoundKb above where it stood when the cases
  // began, and /healthz answers after each.
  const uint64_t base_kb = status_kb(serve_->pid(), "VmRSS");
  ASSERT_GT(base_kb, 0u) << "cannot read the coordinator's VmRSS";
  uint64_t worst_kb = 0;
  std::string worst_case;
  for (const json& c : cases) {
    const bool peak = reset_peak_rss(serve_->pid());
    check_case(c, vars, bases);
    ASSERT_TRUE(serve_->alive()) << "the coordinator died at case " << c["name"] << ":\n" << slurp(work_ / "serve.log");
    const uint64_t used_kb = status_kb(serve_->pid(), peak ? "VmHWM" : "VmRSS");
    const uint64_t grew_kb = used_kb > base_kb ? used_kb - base_kb : 0;
    EXPECT_LE(grew_kb, kCaseMemoryBoundKb) << "case " << c["name"] << " raised the coordinator's memory by " << grew_kb / 1024
                                           << " MB";
    if (grew_kb >= worst_kb) worst_kb = grew_kb, worst_case = c["name"].get<std::string>();
    EXPECT_EQ(call("GET", "/healthz").status, 200u) << "/healthz did not answer after case " << c["name"];
  }
  std::printf("coordinator memory: %llu MB when the cases began; the most any case raised it: %llu MB (%s)\n",
              (unsigned long long)(base_kb / 1024), (unsigned long long)(worst_kb / 1024), worst_case.c_str());
  const json mid = json::parse(call("GET", "/v1/jobs/" + good_job).body, nullptr, false);
  const json tiles = mid.is_object() ? mid.value("tiles", json::object()) : json::object();
  EXPECT_EQ(mid.value("state", ""), "running") << "the good job was not rendering through the cases: " << mid.dump();
  EXPECT_EQ(tiles.value("leased", 0), 1) << "the held tile's lease did not survive the cases: " << mid.dump();
  std::ofstream(release_) << "go";  // the worker carries on
  std::printf("%zu cases in %.1f s; the good job was %s (%s of %s tiles done) when they ended\n", cases.size(),
              std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count(),
              mid.is_object() ? mid.value("state", "?").c_str() : "?", tiles.value("done", json(0)).dump().c_str(),
              tiles.value("total", json(0)).dump().c_str());

  // The good job ends done, bitwise identical to the single-process render; so does a second one submitted now.
  good["priority"] = 0;
  r = call("POST", "/v1/jobs", good.dump());
  ASSERT_EQ(r.status, 201u) << r.body;
  const std::string second_job = json::parse(r.body)["id"].get<std::string>();
  for (const std::string& id : {good_job, second_job}) expect_done_like_reference(id);
  r = call("GET", "/healthz");
  EXPECT_EQ(r.status, 200u);
  EXPECT_TRUE(serve_->alive());
}

// The attacker of a farm with one worker token: it registers sock puppets, each with its own secret, and tries every
// lease id there can be so far (ids are sequential and a registration's id shows the sequence) to fail, heartbeat,
// release and upload the tiles of the good worker, with a puppet's secret or none, and to ask for leases in the good
// worker's name. Every request on a lease that exists is 403: the good job is not failed, no failure is counted
// against anyone, the held tile keeps its lease, and the job ends bitwise identical to a single-process render.
TEST_F(HostileFarm, SockPuppetsCannotFailAnotherWorkersTile) {
  const json good = good_job(16, 32);
  const std::string job = submit_and_hold(good);
  ASSERT_FALSE(job.empty());
  Reply r;
  const json workers = json::parse(call("GET", "/v1/workers").body)["workers"];
  ASSERT_EQ(workers.size(), 1u);
  const std::string victim = workers[0]["id"].get<std::string>();

  std::vector<std::pair<std::string, std::string>> puppets;  // id, secret
  for (int i = 0; i < 3; ++i) {
    r = call("POST", "/v1/workers", json{{"name", "puppet-" + std::to_string(i)}}.dump());
    ASSERT_EQ(r.status, 201u) << r.body;
    const json reg = json::parse(r.body);
    puppets.emplace_back(reg["id"].get<std::string>(), reg["secret"].get<std::string>());
  }
  // "w-<tag>-<n>": every lease so far is "l-<tag>-<k>" with k below n.
  const std::string& last = puppets.back().first;
  const size_t dash = last.rfind('-');
  const std::string tag = last.substr(2, dash - 2);
  const int seq = std::stoi(last.substr(dash + 1));
  int refused = 0;
  for (int k = 1; k < seq; ++k) {
    const std::string lease = "l-" + tag + "-" + std::to_string(k);
    for (const std::string& secret : {puppets[0].second, puppets[1].second, puppets[2].second, std::string()}) {
      const std::map<std::string, std::string> as = {{"X-Tessera-Worker-Secret", secret}};
      r = call("POST", "/v1/leases/" + lease + "/fail", R"({"error": "sabotage"})", as);
      ASSERT_TRUE(r.status == 403 || r.status == 404) << lease << ": " << r.status << " " << r.body;
      if (r.status == 404) break;  // no such lease
      ++refused;
      EXPECT_NE(r.error().find("is worker " + victim + "'s"), std::string::npos) << r.body;
      EXPECT_EQ(call("POST", "/v1/leases/" + lease + "/heartbeat", "{}", as).status, 403u);
      EXPECT_EQ(call("POST", "/v1/leases/" + lease + "/release", "", as).status, 403u);
      EXPECT_EQ(call("PUT", "/v1/leases/" + lease + "/result", "not an exr", as).status, 403u);
    }
  }
  EXPECT_GE(refused, 2 * 4) << "the done tile's lease and the held one, each tried with 4 secrets";
  for (const auto& [id, secret] : puppets)
    EXPECT_EQ(call("POST", "/v1/workers/" + victim + "/lease", "", {{"X-Tessera-Worker-Secret", secret}}).status, 403u);

  const json mid = json::parse(call("GET", "/v1/jobs/" + job).body);
  EXPECT_EQ(mid.value("state", ""), "running") << mid.dump();
  EXPECT_EQ(mid["tiles"].value("leased", 0), 1) << "the held tile lost its lease: " << mid.dump();
  // (Each answer is held in a variable: a range-for over a member of a temporary would read freed memory.)
  const json tiles = json::parse(call("GET", "/v1/jobs/" + job + "/tiles").body);
  ASSERT_FALSE(tiles["tiles"].empty());
  for (const json& t : tiles["tiles"])
    EXPECT_TRUE(t["failures"].empty()) << "a failure was counted: " << t.dump();
  const json workers_after = json::parse(call("GET", "/v1/workers").body);
  ASSERT_EQ(workers_after["workers"].size(), 4u);
  for (const json& w : workers_after["workers"])
    EXPECT_TRUE(w["blocklisted_for"].empty()) << w.dump();
  std::ofstream(release_) << "go";  // the good worker carries on
  expect_done_like_reference(job);
  EXPECT_TRUE(serve_->alive());
}

// A worker-token holder with a lease of its own tries to exhaust the coordinator: a 32 x 32 tile upload whose EXR
// header claims 8192 x 8192 (decoded at the claimed size, 800 MB), and a failure report with a 60 kB error text. The
// upload is refused from its header (422), the text is stored cut to 4096 bytes and marked, the coordinator's peak
// memory rises by less than 64 MB over the whole attack, /healthz answers, and the job still ends bitwise identical to
// a single-process render.
TEST_F(HostileFarm, AWorkersUploadsAndReportsAreBoundedBeforeTheyAllocate) {
  const json good = good_job(16, 32);
  const std::string job = submit_and_hold(good);
  ASSERT_FALSE(job.empty());
  Reply r;

  r = call("POST", "/v1/workers", json{{"name", "attacker"}}.dump());
  ASSERT_EQ(r.status, 201u) << r.body;
  const json reg = json::parse(r.body);
  const std::map<std::string, std::string> as = {{"X-Tessera-Worker-Secret", reg["secret"].get<std::string>()}};
  const uint64_t base_kb = status_kb(serve_->pid(), "VmRSS");
  ASSERT_TRUE(reset_peak_rss(serve_->pid())) << "the kernel refused to reset the peak memory";

  const auto take_lease = [&] {
    const Reply l = call("POST", "/v1/workers/" + reg["id"].get<std::string>() + "/lease", "{}", as);
    EXPECT_EQ(l.status, 200u) << l.body;
    return l.status == 200 ? json::parse(l.body) : json();
  };
  json lease = take_lease();
  ASSERT_TRUE(lease.is_object());
  const json w = lease["window"];
  const int x0 = w[0], y0 = w[1], x1 = w[2], y1 = w[3];
  ExrWriteOptions opt;
  opt.data_window = PixelWindow{x0, y0, x1, y1};
  opt.display_window = PixelWindow{0, 0, good["scene"]["film"]["resolution"][0].get<int>(),
                                   good["scene"]["film"]["resolution"][1].get<int>()};
  write_exr(work_ / "bomb.exr", Image::make(x1 - x0, y1 - y0), opt);
  std::string bomb = slurp(work_ / "bomb.exr");
  const std::string key("dataWindow\0box2i\0", 17);
  const size_t at = bomb.find(key);
  ASSERT_NE(at, std::string::npos);
  const int32_t claim[4] = {0, 0, 8191, 8191};  // xMin, yMin, xMax, yMax (inclusive), little-endian
  std::memcpy(bomb.data() + at + key.size() + 4, claim, sizeof claim);
  const std::string lease_id = lease["lease"].get<std::string>();
  r = call("PUT", "/v1/leases/" + lease_id + "/result", bomb, as);
  EXPECT_EQ(r.status, 422u) << r.body;
  EXPECT_NE(r.error().find("data window is [0, 0, 8192, 8192)"), std::string::npos) << r.body;
  EXPECT_EQ(call("GET", "/healthz").status, 200u);

  // The refused upload blocklists nothing yet (one failure); the next lease gets a long failure text.
  lease = take_lease();
  ASSERT_TRUE(lease.is_object());
  const std::string long_error(60'000, 'e');
  r = call("POST", "/v1/leases/" + lease["lease"].get<std::string>() + "/fail", json{{"error", long_error}}.dump(), as);
  EXPECT_EQ(r.status, 200u) << r.body;
  const uint64_t peak_kb = status_kb(serve_->pid(), "VmHWM");
  EXPECT_LT(peak_kb, base_kb + kCaseMemoryBoundKb) << "the attack raised the coordinator's peak memory from "
                                                    << base_kb / 1024 << " to " << peak_kb / 1024 << " MB";
  std::printf("coordinator memory: %llu MB before the attacker's upload and report, peak %llu MB during them\n",
              (unsigned long long)(base_kb / 1024), (unsigned long long)(peak_kb / 1024));
  bool cut_found = false;
  const json tiles = json::parse(call("GET", "/v1/jobs/" + job + "/tiles").body);  // held: see the test above
  for (const json& t : tiles["tiles"])
    for (const json& f : t["failures"]) {
      const std::string text = f.dump();
      EXPECT_LT(text.size(), 8192u) << "a stored failure text is not bounded";
      if (text.find("[cut from 60000 bytes]") != std::string::npos) cut_found = true;
    }
  EXPECT_TRUE(cut_found) << "the long failure text was not stored cut and marked";
  EXPECT_EQ(call("GET", "/healthz").status, 200u);

  std::ofstream(release_) << "go";  // the good worker carries on and renders the attacker's tiles again
  expect_done_like_reference(job);
  EXPECT_TRUE(serve_->alive());
}

}  // namespace
}  // namespace tessera
