#include "tools/viewer/log_follower.h"

#include <cstdio>
#include <fstream>
#include <iterator>

#include <gtest/gtest.h>

#include "common/bus/lcm_log.h"
#include "tests/testing/scratch.h"

namespace anchormap::viewer {
namespace {

std::vector<uint8_t> ReadAll(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  return std::vector<uint8_t>(std::istreambuf_iterator<char>(in), {});
}

void WriteBytes(const std::string& path, const std::vector<uint8_t>& bytes, size_t from, size_t to,
                bool append) {
  std::ofstream out(path, std::ios::binary | (append ? std::ios::app : std::ios::trunc));
  out.write(reinterpret_cast<const char*>(bytes.data() + from),
            static_cast<std::streamsize>(to - from));
}

class LogFollowerTest : public ::testing::Test {
 protected:
  void SetUp() override {
    const std::string dir = ::anchormap::testing::ScratchDir().string();
    source_ = dir + "/follower_source.lcmlog";
    followed_ = dir + "/follower_followed.lcmlog";
    std::remove(followed_.c_str());
    LcmLogWriter writer;
    ASSERT_TRUE(writer.Open(source_).ok());
    for (int i = 0; i < 5; ++i) {
      std::vector<uint8_t> data(100 + 10 * i, static_cast<uint8_t>(i));
      ASSERT_TRUE(
          writer.WriteRaw("CHANNEL_" + std::to_string(i), 1000 + i, data.data(), data.size()).ok());
    }
    writer.Close();
    bytes_ = ReadAll(source_);
  }
  std::string source_, followed_;
  std::vector<uint8_t> bytes_;
};

TEST_F(LogFollowerTest, ReturnsEachEventOnceAsTheFileGrowsByteRangesAtATime) {
  LogFollower follower(followed_);
  EXPECT_TRUE(follower.Poll().empty());  // no file yet
  std::vector<FollowedEvent> events;
  for (size_t from = 0; from < bytes_.size(); from += 37) {  // cuts events anywhere
    WriteBytes(followed_, bytes_, from, std::min(bytes_.size(), from + 37), from > 0);
    for (FollowedEvent& e : follower.Poll()) events.push_back(std::move(e));
  }
  ASSERT_EQ(events.size(), 5u);
  for (int i = 0; i < 5; ++i) {
    EXPECT_EQ(events[i].channel, "CHANNEL_" + std::to_string(i));
    EXPECT_EQ(events[i].utime, 1000 + i);
    EXPECT_EQ(events[i].data, std::vector<uint8_t>(100 + 10 * i, static_cast<uint8_t>(i)));
  }
  EXPECT_EQ(follower.bytes_skipped(), 0);
  EXPECT_TRUE(follower.Poll().empty());
}

TEST_F(LogFollowerTest, SkipsGarbageToTheNextEventAndStartsAgainOnANewFile) {
  std::vector<uint8_t> garbage = {1, 2, 3, 0xED, 0xA1, 9};
  WriteBytes(followed_, garbage, 0, garbage.size(), false);
  WriteBytes(followed_, bytes_, 0, bytes_.size(), true);
  LogFollower follower(followed_);
  EXPECT_EQ(follower.Poll().size(), 5u);
  EXPECT_EQ(follower.bytes_skipped(), 6);
  // Replaced by a shorter file (a new run): read from its start.
  std::remove(followed_.c_str());
  WriteBytes(followed_, bytes_, 0, bytes_.size() / 2, false);
  const auto again = follower.Poll();
  ASSERT_GE(again.size(), 1u);
  EXPECT_EQ(again[0].channel, "CHANNEL_0");
  EXPECT_EQ(follower.reopens(), 1);
}

}  // namespace
}  // namespace anchormap::viewer
