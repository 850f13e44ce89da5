// The client's SSE parser: events split at any byte, comments, CRLF, several data lines, stopping early.
#include "client/sse_parser.h"

#include <gtest/gtest.h>

#include <vector>

namespace tessera::client {
namespace {

TEST(SseParser, EventsSplitAnywhereAreReassembled) {
  const std::string text =
      "retry: 1000\n\n: keep-alive\n\nid: r-1\nevent: job\ndata: {\"id\":\"j-1\"}\n\n"
      "id: r-2\r\nevent: tile_done\r\ndata: a\r\ndata: b\r\n\r\ndata: plain\n\n";
  for (size_t cut = 0; cut <= text.size(); ++cut) {
    std::vector<SseMessage> got;
    SseParser p([&](const SseMessage& m) {
      got.push_back(m);
      return true;
    });
    EXPECT_TRUE(p.feed(std::string_view(text).substr(0, cut)));
    EXPECT_TRUE(p.feed(std::string_view(text).substr(cut)));
    ASSERT_EQ(got.size(), 3u) << cut;
    EXPECT_EQ(got[0].id, "r-1");
    EXPECT_EQ(got[0].event, "job");
    EXPECT_EQ(got[0].data, "{\"id\":\"j-1\"}");
    EXPECT_EQ(got[1].event, "tile_done");
    EXPECT_EQ(got[1].data, "a\nb");
    EXPECT_EQ(got[2].event, "message");
    EXPECT_EQ(got[2].id, "r-2");  // an id holds until the next one
    EXPECT_EQ(got[2].data, "plain");
  }
}

TEST(SseParser, StopsWhenAskedTo) {
  int seen = 0;
  SseParser p([&](const SseMessage&) { return ++seen < 2; });
  EXPECT_FALSE(p.feed("data: 1\n\ndata: 2\n\ndata: 3\n\n"));
  EXPECT_EQ(seen, 2);
}

}  // namespace
}  // namespace tessera::client
