#include "client/http_message.h"

#include <boost/beast/http/field.hpp>
#include <gtest/gtest.h>

namespace tessera::client {
namespace {

namespace http = boost::beast::http;

TEST(HttpMessage, ARequestCarriesTheUrlsPrefixHostTokenFieldsAndLength) {
  const HttpUrl url = parse_http_url("http://farm.lan:8470/tessera");
  HttpRequest r = make_request("POST", "/v1/workers", "{\"a\":1}");
  r.headers["X-Tessera-Worker-Secret"] = "s3";
  const auto req = beast_request(url, "tok", r, http::verb::post);
  EXPECT_EQ(req.method(), http::verb::post);
  EXPECT_EQ(req.target(), "/tessera/v1/workers");
  EXPECT_EQ(req.version(), 11u);
  EXPECT_EQ(req[http::field::host], "farm.lan:8470");
  EXPECT_EQ(req[http::field::user_agent], "tessera/" TESSERA_VERSION);
  EXPECT_EQ(req[http::field::content_type], "application/json");
  EXPECT_EQ(req["X-Tessera-Worker-Secret"], "s3");
  EXPECT_EQ(req[http::field::authorization], "Bearer tok");
  EXPECT_EQ(req[http::field::content_length], "7");
  EXPECT_EQ(req.body(), "{\"a\":1}");
  EXPECT_TRUE(req.keep_alive());
}

TEST(HttpMessage, ABodilessGetHasNoContentTypeLengthOrToken) {
  const auto req = beast_request(parse_http_url("http://127.0.0.1:1"), "", make_request("GET", "/v1/jobs"),
                                 http::verb::get);
  EXPECT_EQ(req.target(), "/v1/jobs");
  EXPECT_EQ(req.count(http::field::content_type), 0u);
  EXPECT_EQ(req.count(http::field::content_length), 0u);
  EXPECT_EQ(req.count(http::field::authorization), 0u);
}

TEST(HttpMessage, AnEmptyPostStillSaysItsLengthIsZero) {
  HttpRequest r = make_request("POST", "/v1/workers/w/lease");
  r.content_type = "application/json";  // as a worker's bare lease request
  const auto req = beast_request(parse_http_url("http://127.0.0.1:1"), "", r, http::verb::post);
  EXPECT_EQ(req[http::field::content_type], "application/json");
  EXPECT_EQ(req[http::field::content_length], "0");
}

TEST(HttpMessage, AnAnswersHeadHasItsStatusAndLowercasedFieldNames) {
  http::response_header<> head;
  head.result(http::status::gone);
  head.set("X-Tessera-Thing", "v");
  const HttpResponse r = response_head(head);
  EXPECT_EQ(r.status, 410);
  EXPECT_EQ(r.headers.at("x-tessera-thing"), "v");
  EXPECT_EQ(r.header("X-TESSERA-THING"), "v");
  EXPECT_TRUE(r.body.empty());
}

}  // namespace
}  // namespace tessera::client
