#include "common/util/log.h"

#include <string>
#include <vector>

#include <gtest/gtest.h>

namespace anchormap {
namespace {

class LogTest : public ::testing::Test {
 protected:
  void SetUp() override {
    SetLogSink([this](LogLevel, const std::string& line) { lines_.push_back(line); });
    SetMinLogLevel(LogLevel::kInfo);
    SetLogComponent("test");
  }
  void TearDown() override {
    SetLogSink(nullptr);
    SetMinLogLevel(LogLevel::kInfo);
    SetLogComponent("anchormap");
  }
  std::vector<std::string> lines_;
};

TEST_F(LogTest, FormatsOneLineWithLevelAndComponent) {
  LogWarning("hello");
  ASSERT_EQ(lines_.size(), 1u);
  EXPECT_NE(lines_[0].find(" W [test] hello"), std::string::npos) << lines_[0];
  EXPECT_EQ(lines_[0].find('\n'), std::string::npos);
}

TEST_F(LogTest, DropsMessagesBelowTheMinimumLevel) {
  LogDebug("hidden");
  LogInfo("shown");
  SetMinLogLevel(LogLevel::kError);
  LogWarning("hidden too");
  LogError("shown too");
  ASSERT_EQ(lines_.size(), 2u);
  EXPECT_NE(lines_[0].find("shown"), std::string::npos);
  EXPECT_NE(lines_[1].find("shown too"), std::string::npos);
}

TEST_F(LogTest, OncePerKindLogsFirstOfEachKindAndCountsAll) {
  OncePerKindLog once;
  EXPECT_TRUE(once.Log(LogLevel::kWarning, "nan", "a NaN"));
  EXPECT_FALSE(once.Log(LogLevel::kWarning, "nan", "a NaN"));
  EXPECT_TRUE(once.Log(LogLevel::kWarning, "size", "too big"));
  EXPECT_FALSE(once.Log(LogLevel::kWarning, "nan", "a NaN"));
  EXPECT_EQ(lines_.size(), 2u);
  EXPECT_EQ(once.count("nan"), 3);
  EXPECT_EQ(once.count("size"), 1);
  EXPECT_EQ(once.count("other"), 0);
}

TEST_F(LogTest, EveryNLogsFirstAndEveryNth) {
  EveryNLog every(3);
  int logged = 0;
  for (int i = 0; i < 7; ++i) logged += every.Log(LogLevel::kInfo, "tick") ? 1 : 0;
  EXPECT_EQ(logged, 3);  // calls 1, 4 and 7
  EXPECT_EQ(every.count(), 7);
  ASSERT_EQ(lines_.size(), 3u);
  EXPECT_NE(lines_[2].find("[7 so far]"), std::string::npos) << lines_[2];
}

TEST(LogLevelTest, ParsesNames) {
  LogLevel level = LogLevel::kInfo;
  EXPECT_TRUE(ParseLogLevel("debug", &level));
  EXPECT_EQ(level, LogLevel::kDebug);
  EXPECT_TRUE(ParseLogLevel("warn", &level));
  EXPECT_EQ(level, LogLevel::kWarning);
  EXPECT_FALSE(ParseLogLevel("loud", &level));
  EXPECT_EQ(level, LogLevel::kWarning);
}

}  // namespace
}  // namespace anchormap
