#include "common/bus/lcm_log.h"

#include <filesystem>

#include <gtest/gtest.h>

#include "bot_core/pose_t.hpp"

namespace anchormap {
namespace {

TEST(LcmLogTest, WritesAndReadsTypedEvents) {
  const std::string path =
      (std::filesystem::temp_directory_path() / "anchormap_lcm_log_test.lcmlog").string();
  {
    LcmLogWriter writer;
    ASSERT_TRUE(writer.Open(path).ok());
    for (int i = 0; i < 3; ++i) {
      bot_core::pose_t pose{};
      pose.utime = 1000 * i;
      pose.pos[0] = i;
      ASSERT_TRUE(writer.Write("R1_ODOMETRY", pose.utime, pose).ok());
    }
  }
  LcmLogReader reader;
  ASSERT_TRUE(reader.Open(path).ok());
  int count = 0;
  while (auto event = reader.Next()) {
    EXPECT_EQ(event->channel, "R1_ODOMETRY");
    auto pose = DecodeAs<bot_core::pose_t>(*event);
    ASSERT_TRUE(pose.has_value());
    EXPECT_EQ(pose->pos[0], count);
    EXPECT_EQ(event->utime, 1000 * count);
    ++count;
  }
  EXPECT_EQ(count, 3);
  std::filesystem::remove(path);
  EXPECT_FALSE(reader.Open("/nonexistent/dir/x.lcmlog").ok());
}

}  // namespace
}  // namespace anchormap
