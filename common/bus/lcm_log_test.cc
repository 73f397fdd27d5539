#include "common/bus/lcm_log.h"

#include <filesystem>
#include <fstream>
#include <iterator>
#include <vector>

#include <gtest/gtest.h>

#include "bot_core/pose_t.hpp"
#include "tests/testing/scratch.h"

namespace anchormap {
namespace {

TEST(LcmLogTest, WritesAndReadsTypedEvents) {
  const std::string path = ::anchormap::testing::ScratchPath("test.lcmlog");
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

// Flush hands the events to the file while the writer stays open: a reader following the
// file (a test waiting for a recorder to catch up, the viewer) sees them.
TEST(LcmLogTest, FlushMakesEventsVisibleBeforeClose) {
  const std::string path = ::anchormap::testing::ScratchPath("flush.lcmlog");
  LcmLogWriter writer;
  ASSERT_TRUE(writer.Open(path).ok());
  const std::vector<uint8_t> payload(100, 7);
  ASSERT_TRUE(writer.WriteRaw("CHANNEL", 5, payload.data(), payload.size()).ok());
  ASSERT_TRUE(writer.Flush().ok());
  LcmLogReader reader;
  ASSERT_TRUE(reader.Open(path).ok());
  auto event = reader.Next();
  ASSERT_TRUE(event.has_value());
  EXPECT_EQ(event->channel, "CHANNEL");
  EXPECT_EQ(event->data, payload);
  writer.Close();
  EXPECT_FALSE(writer.Flush().ok());
}

// Five events; the third's sync word and the fourth's channel length are overwritten and
// garbage ends the file: the reader names each corrupt offset, resynchronises at the next
// sound event and returns the others intact.
TEST(LcmLogTest, ReportsAndSkipsCorruptEvents) {
  const std::string path = ::anchormap::testing::ScratchPath("corrupt.lcmlog");
  {
    LcmLogWriter writer;
    ASSERT_TRUE(writer.Open(path).ok());
    for (int i = 0; i < 5; ++i) {
      bot_core::pose_t pose{};
      pose.utime = 1000 * i;
      pose.pos[0] = i;
      ASSERT_TRUE(writer.Write("R1_ODOMETRY", pose.utime, pose).ok());
    }
  }
  std::vector<char> bytes;
  {
    std::ifstream in(path, std::ios::binary);
    bytes.assign(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
  }
  const size_t event_bytes = bytes.size() / 5;  // equal events
  ASSERT_EQ(event_bytes * 5, bytes.size());
  bytes[2 * event_bytes] = 0x00;                     // sync word of event 2
  bytes[3 * event_bytes + 20] = 0x7f;                // channel length of event 3
  bytes.insert(bytes.end(), {'\xED', '\xA1', 'x'});  // a torn last write
  {
    std::ofstream out(path, std::ios::binary | std::ios::trunc);
    out.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
  }
  LcmLogReader reader;
  ASSERT_TRUE(reader.Open(path).ok());
  std::vector<double> xs;
  while (auto event = reader.Next()) {
    auto pose = DecodeAs<bot_core::pose_t>(*event);
    ASSERT_TRUE(pose.has_value());
    xs.push_back(pose->pos[0]);
  }
  EXPECT_EQ(xs, (std::vector<double>{0, 1, 4}));
  ASSERT_EQ(reader.problems().size(), 2u);
  EXPECT_NE(reader.problems()[0].find("byte " + std::to_string(2 * event_bytes) + " (bad sync"),
            std::string::npos)
      << reader.problems()[0];
  EXPECT_NE(reader.problems()[0].find("next event at byte " + std::to_string(4 * event_bytes)),
            std::string::npos)
      << reader.problems()[0];
  EXPECT_NE(reader.problems()[1].find("byte " + std::to_string(5 * event_bytes)), std::string::npos)
      << reader.problems()[1];
  EXPECT_NE(reader.problems()[1].find("end of the file"), std::string::npos)
      << reader.problems()[1];
  std::filesystem::remove(path);
}

}  // namespace
}  // namespace anchormap
