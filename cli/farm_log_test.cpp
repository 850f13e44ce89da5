#include "cli/farm_log.h"
#include "tests/support/test_files.h"

#include <gtest/gtest.h>
#include <spdlog/sinks/ostream_sink.h>
#include <spdlog/spdlog.h>

#include <fstream>
#include <sstream>
#include <string>
#include <thread>

namespace tessera::cli {
namespace {

class FarmLogTest : public testing::TempDirTest {
 protected:
  void SetUp() override {
    TempDirTest::SetUp();
    before_ = spdlog::default_logger();
    auto terminal = std::make_shared<spdlog::logger>("terminal", std::make_shared<spdlog::sinks::ostream_sink_mt>(terminal_));
    terminal->set_pattern("%l %v");
    terminal->set_level(spdlog::level::info);
    spdlog::set_default_logger(terminal);
  }
  void TearDown() override {
    spdlog::set_default_logger(before_);
    TempDirTest::TearDown();
  }
  std::string file_text(const std::string& name) const {
    std::ifstream in(file(name));
    return std::string(std::istreambuf_iterator<char>(in), {});
  }

  std::ostringstream terminal_;
  std::shared_ptr<spdlog::logger> before_;
};

TEST_F(FarmLogTest, TheCommandsThreadSpeaksToTheTerminalAndOtherThreadsToTheFile) {
  {
    FarmLog log(file("serve.log"));
    spdlog::info("the command's line");
    std::thread([] { spdlog::info("a coordinator's line"); }).join();
  }
  EXPECT_NE(terminal_.str().find("info the command's line"), std::string::npos);
  EXPECT_EQ(terminal_.str().find("coordinator"), std::string::npos);
  const std::string served = file_text("serve.log");
  EXPECT_NE(served.find("[info] a coordinator's line"), std::string::npos);
  EXPECT_EQ(served.find("command"), std::string::npos);
}

TEST_F(FarmLogTest, TheTerminalKeepsItsLevelTheFileGetsInformationAndTheLoggerComesBack) {
  spdlog::default_logger()->set_level(spdlog::level::warn);  // as a quiet command's
  const auto terminal = spdlog::default_logger();
  {
    FarmLog log(file("serve.log"));
    spdlog::info("not for a quiet terminal");
    spdlog::warn("for every terminal");
    std::thread([] { spdlog::info("kept in the file"); }).join();
    // The file is written as each line comes, so it can be read while the farm runs.
    EXPECT_NE(file_text("serve.log").find("kept in the file"), std::string::npos);
  }
  EXPECT_EQ(terminal_.str().find("not for a quiet terminal"), std::string::npos);
  EXPECT_NE(terminal_.str().find("warning for every terminal"), std::string::npos);
  EXPECT_EQ(spdlog::default_logger(), terminal);
}

}  // namespace
}  // namespace tessera::cli
