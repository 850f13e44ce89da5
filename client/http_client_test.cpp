#include "client/http_client.h"

#include <boost/asio/ip/tcp.hpp>
#include <boost/beast/core/flat_buffer.hpp>
#include <boost/beast/http/empty_body.hpp>
#include <boost/beast/http/read.hpp>
#include <boost/beast/http/string_body.hpp>
#include <boost/beast/http/write.hpp>
#include <gtest/gtest.h>

#include <atomic>
#include <functional>
#include <thread>

namespace tessera::client {
namespace {

namespace asio = boost::asio;
namespace http = boost::beast::http;
using tcp = asio::ip::tcp;

// A loopback server running `handle` on each connection in a background thread.
class TestServer {
 public:
  using Handler = std::function<void(tcp::socket&)>;
  explicit TestServer(Handler handle) : acceptor_(ioc_, tcp::endpoint(asio::ip::make_address("127.0.0.1"), 0)) {
    thread_ = std::thread([this, handle] {
      while (true) {
        tcp::socket s(ioc_);
        boost::system::error_code ec;
        acceptor_.accept(s, ec);
        if (ec || stopping_) return;
        ++connections;
        try {
          handle(s);
        } catch (...) {
        }
      }
    });
  }
  ~TestServer() {
    stopping_ = true;
    // Wake the blocking accept with a connection of our own.
    boost::system::error_code ec;
    tcp::socket poke(ioc_);
    poke.connect(acceptor_.local_endpoint(), ec);
    thread_.join();
  }
  std::string url() const { return "http://127.0.0.1:" + std::to_string(acceptor_.local_endpoint().port()); }
  std::atomic<int> connections{0};

 private:
  asio::io_context ioc_;
  tcp::acceptor acceptor_;
  std::atomic<bool> stopping_{false};
  std::thread thread_;
};

// Serves requests on one connection, echoing method, target and body; closes after `max_requests`.
void echo(tcp::socket& s, int max_requests) {
  boost::beast::flat_buffer buf;
  for (int i = 0; i < max_requests; ++i) {
    http::request<http::string_body> req;
    http::read(s, buf, req);
    http::response<http::string_body> res{http::status::ok, 11};
    res.set(http::field::content_type, "text/plain");
    res.set("X-Echo-Header", std::string(req["X-Test"]));
    res.body() = std::string(req.method_string()) + " " + std::string(req.target()) + " " + req.body();
    res.keep_alive(i + 1 < max_requests);
    res.prepare_payload();
    http::write(s, res);
  }
}

TEST(ParseHttpUrl, AcceptsHostPortAndPrefix) {
  const HttpUrl u = parse_http_url("http://127.0.0.1:8470/farm/");
  EXPECT_EQ(u.host, "127.0.0.1");
  EXPECT_EQ(u.port, "8470");
  EXPECT_EQ(u.base_path, "/farm");
  EXPECT_EQ(parse_http_url("localhost:9").port, "9");
  EXPECT_EQ(parse_http_url("http://example").port, "80");
  EXPECT_EQ(parse_http_url("http://[::1]:81").host, "::1");
  EXPECT_FALSE(u.tls);
}

TEST(ParseHttpUrl, AcceptsHttpsWithItsDefaultPort) {
  const HttpUrl u = parse_http_url("https://coordinator.example/farm");
  EXPECT_TRUE(u.tls);
  EXPECT_EQ(u.port, "443");
  EXPECT_EQ(u.to_string(), "https://coordinator.example:443/farm");
  EXPECT_EQ(parse_http_url("https://10.0.0.5:8470").port, "8470");
}

TEST(HttpClientTls, RefusesTlsFilesWithPlainHttpAndUnusableFiles) {
  ClientTlsFiles ca;
  ca.ca_file = "/nonexistent/ca.pem";
  // Naming a CA for an http:// URL would suggest a verification that never happens.
  EXPECT_THROW(HttpClient(parse_http_url("http://127.0.0.1:1"), {}, 1024, ca), std::invalid_argument);
  EXPECT_THROW(HttpClient(parse_http_url("https://127.0.0.1:1"), {}, 1024, ca), std::invalid_argument);
  ClientTlsFiles half;
  half.cert_file = "/etc/hostname";
  EXPECT_THROW(HttpClient(parse_http_url("https://127.0.0.1:1"), {}, 1024, half), std::invalid_argument);
  EXPECT_NO_THROW(HttpClient(parse_http_url("https://127.0.0.1:1")));  // the system CA store
}

TEST(ParseHttpUrl, RejectsWhatItCannotUse) {
  EXPECT_THROW(parse_http_url("ftp://x:1"), std::invalid_argument);
  EXPECT_THROW(parse_http_url("http://:80"), std::invalid_argument);
  EXPECT_THROW(parse_http_url("http://x:0"), std::invalid_argument);
  EXPECT_THROW(parse_http_url("http://x:99999"), std::invalid_argument);
  EXPECT_THROW(parse_http_url("http://x:8a"), std::invalid_argument);
}

TEST(HttpResponse, ErrorTextPrefersTheJsonErrorField) {
  HttpResponse r;
  r.status = 400;
  r.body = R"j({"error": "scene: objects[3].radius: must not be negative (got -1)"})j";
  EXPECT_EQ(r.error_text(), "scene: objects[3].radius: must not be negative (got -1)");
  r.body = "plain words\n";
  EXPECT_EQ(r.error_text(), "plain words");
  r.body.clear();
  EXPECT_EQ(r.error_text(), "HTTP 400");
}

TEST(HttpClient, SendsAndReceivesOverOneKeptAliveConnection) {
  TestServer server([](tcp::socket& s) { echo(s, 100); });
  HttpClient c(parse_http_url(server.url()));
  HttpRequest req;
  req.method = "PUT";
  req.target = "/v1/blobs/x";
  req.body = "hello";
  req.headers["X-Test"] = "yes";
  const HttpResponse r = c.send(req);
  EXPECT_EQ(r.status, 200);
  EXPECT_EQ(r.body, "PUT /v1/blobs/x hello");
  EXPECT_EQ(r.header("x-echo-header"), "yes");
  EXPECT_EQ(r.header("Content-Type"), "text/plain");
  EXPECT_EQ(c.send("GET", "/a").body, "GET /a ");
  EXPECT_EQ(server.connections.load(), 1);
}

// Answers one request on the connection, saying keep-alive.
void answer_one(tcp::socket& s, boost::beast::flat_buffer& buf) {
  http::request<http::string_body> req;
  http::read(s, buf, req);
  http::response<http::string_body> res{http::status::ok, 11};
  res.body() = std::string(req.target());
  res.keep_alive(true);
  res.prepare_payload();
  http::write(s, res);
}

TEST(HttpClient, ReplacesAKeptAliveConnectionTheServerClosed) {
  // The server answers one request per connection but does not say so (keep-alive), then closes.
  std::atomic<int> closed{0};
  TestServer server([&](tcp::socket& s) {
    boost::beast::flat_buffer buf;
    answer_one(s, buf);
    s.shutdown(tcp::socket::shutdown_both);
    s.close();
    ++closed;
  });
  HttpClient c(parse_http_url(server.url()));
  EXPECT_EQ(c.send("POST", "/1").body, "/1");
  while (closed.load() == 0) std::this_thread::yield();  // the close has reached the client's socket (loopback)
  EXPECT_EQ(c.send("POST", "/2").body, "/2");
  EXPECT_EQ(server.connections.load(), 2);
}

// The server answers a connection's first request, then reads the next one and closes without an answer.
class LosesSecondAnswer {
 public:
  LosesSecondAnswer()
      : server_([this](tcp::socket& s) {
          boost::beast::flat_buffer buf;
          answer_one(s, buf);
          ++requests;
          http::request<http::string_body> req;
          http::read(s, buf, req);
          ++requests;
          s.shutdown(tcp::socket::shutdown_both);
          s.close();
        }) {}
  std::string url() const { return server_.url(); }
  int connections() const { return server_.connections.load(); }
  std::atomic<int> requests{0};

 private:
  TestServer server_;
};

TEST(HttpClient, AnIdempotentRequestWhoseAnswerWasLostGoesOnceMore) {
  LosesSecondAnswer server;
  HttpClient c(parse_http_url(server.url()));
  EXPECT_EQ(c.send("GET", "/1").body, "/1");
  EXPECT_EQ(c.send("PUT", "/2", "x").body, "/2");  // lost on the first connection, answered on a second
  EXPECT_EQ(server.requests.load(), 3);
  EXPECT_EQ(server.connections(), 2);
}

TEST(HttpClient, APostWhoseAnswerWasLostIsNotSentAgain) {
  LosesSecondAnswer server;
  HttpClient c(parse_http_url(server.url()));
  EXPECT_EQ(c.send("GET", "/1").body, "/1");
  try {
    c.send("POST", "/v1/jobs", "{}");
    FAIL() << "a lost answer to a POST was not reported";
  } catch (const TransportError& e) {
    EXPECT_NE(std::string(e.what()).find("may or may not have been carried out"), std::string::npos) << e.what();
  }
  EXPECT_EQ(server.requests.load(), 2);  // the POST reached the server once
  EXPECT_EQ(server.connections(), 1);
  EXPECT_EQ(c.send("GET", "/3").body, "/3");  // the client goes on with a fresh connection
}

TEST(HttpClient, ReadTimeoutTurnsASilentServerIntoAnError) {
  std::atomic<bool> release{false};
  TestServer server([&](tcp::socket& s) {
    boost::beast::flat_buffer buf;
    http::request<http::string_body> req;
    http::read(s, buf, req);
    while (!release) std::this_thread::sleep_for(std::chrono::milliseconds(10));  // never answers
  });
  HttpClient c(parse_http_url(server.url()), HttpTimeouts{std::chrono::milliseconds(1000), std::chrono::milliseconds(1000),
                                                          std::chrono::milliseconds(200)});
  try {
    c.send("GET", "/slow");
    FAIL() << "no timeout";
  } catch (const TransportError& e) {
    EXPECT_NE(std::string(e.what()).find("timed out after 200 ms"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("GET http://127.0.0.1:"), std::string::npos) << e.what();
  }
  release = true;
}

TEST(HttpClient, AnInterruptedRequestClosesItsConnectionAndSaysSo) {
  // A server that holds the request (as a coordinator holds a lease request for work) until the test lets it go.
  std::atomic<bool> release{false};
  std::atomic<int> requests{0};
  TestServer server([&](tcp::socket& s) {
    boost::beast::flat_buffer buf;
    http::request<http::string_body> req;
    http::read(s, buf, req);
    ++requests;
    while (!release) std::this_thread::sleep_for(std::chrono::milliseconds(10));  // never answers
  });
  HttpClient c(parse_http_url(server.url()));  // default timeouts: 30 s to read, far beyond this test
  std::atomic<bool> stop{false};
  std::atomic<int> asked{0};
  std::thread stopper([&] {
    while (requests.load() == 0) std::this_thread::yield();  // the request is under way
    stop = true;
  });
  HttpRequest r;
  r.method = "POST";
  r.target = "/held";
  r.body = "{}";
  try {
    c.send(r, [&] {
      ++asked;
      return stop.load();
    });
    FAIL() << "the request was not interrupted";
  } catch (const RequestInterrupted& e) {
    EXPECT_NE(std::string(e.what()).find("POST http://127.0.0.1:"), std::string::npos) << e.what();
  }
  stopper.join();
  EXPECT_GE(asked.load(), 1);
  EXPECT_EQ(requests.load(), 1);  // a POST is never sent again behind the caller's back
  release = true;
}

TEST(HttpClient, ConnectionRefusedIsATransportError) {
  // Find a free port by binding and closing.
  asio::io_context ioc;
  tcp::acceptor a(ioc, tcp::endpoint(asio::ip::make_address("127.0.0.1"), 0));
  const auto port = a.local_endpoint().port();
  a.close();
  HttpClient c(parse_http_url("http://127.0.0.1:" + std::to_string(port)));
  try {
    c.send("POST", "/v1/workers", "{}");
    FAIL() << "connected to a closed port";
  } catch (const TransportError& e) {
    EXPECT_NE(std::string(e.what()).find("cannot connect"), std::string::npos) << e.what();
  }
}

TEST(HttpClient, HeadResponsesHaveNoBody) {
  TestServer server([](tcp::socket& s) {
    boost::beast::flat_buffer buf;
    for (int i = 0; i < 2; ++i) {
      http::request<http::string_body> req;
      http::read(s, buf, req);
      http::response<http::empty_body> res{req.method() == http::verb::head ? http::status::not_found : http::status::ok, 11};
      res.content_length(req.method() == http::verb::head ? 1234 : 0);
      res.keep_alive(true);
      http::write(s, res);
    }
  });
  HttpClient c(parse_http_url(server.url()));
  EXPECT_EQ(c.send("HEAD", "/v1/blobs/abc").status, 404);
  EXPECT_EQ(c.send("GET", "/next").status, 200);  // the connection is still in step
}

}  // namespace
}  // namespace tessera::client
