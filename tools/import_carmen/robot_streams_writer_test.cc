#include "tools/import_carmen/robot_streams_writer.h"

#include <cmath>
#include <filesystem>

#include <gtest/gtest.h>

#include "common/bus/lcm_log.h"
#include "tests/testing/scratch.h"

namespace anchormap {
namespace {

TEST(ToPoseMessageTest, PlanarPoseAsBotCorePose) {
  const bot_core::pose_t m = ToPoseMessage(42, Pose2(1.0, 2.0, M_PI / 2), 0.5, 0.25);
  EXPECT_EQ(m.utime, 42);
  EXPECT_EQ(m.pos[0], 1.0);
  EXPECT_EQ(m.pos[1], 2.0);
  EXPECT_EQ(m.pos[2], 0.0);
  EXPECT_NEAR(m.orientation[0], std::sqrt(0.5), 1e-15);  // w
  EXPECT_EQ(m.orientation[1], 0.0);
  EXPECT_EQ(m.orientation[2], 0.0);
  EXPECT_NEAR(m.orientation[3], std::sqrt(0.5), 1e-15);  // z
  EXPECT_NEAR(m.vel[0], 0.0, 1e-15);                     // heading +y: velocity along +y
  EXPECT_NEAR(m.vel[1], 0.5, 1e-15);
  EXPECT_EQ(m.rotation_rate[2], 0.25);
}

TEST(ChannelsTest, PatternsAndValidation) {
  EXPECT_EQ(ChannelName("{robot}_ODOMETRY", "R2"), "R2_ODOMETRY");
  EXPECT_EQ(ChannelName("X_{robot}_{robot}", "R2"), "X_R2_R2");
  ImportChannels channels;
  EXPECT_TRUE(channels.Validate().ok());
  channels.laser = "LASER";
  EXPECT_EQ(channels.Validate().message(),
            "laser channel pattern 'LASER' does not contain {robot}");
  channels.laser = "{robot}_laser";
  EXPECT_EQ(channels.Validate().message(),
            "laser channel pattern '{robot}_laser' does not give an upper-case channel name");
}

TEST(WriteRobotStreamsTest, MergesRobotsInTimeOrderOdometryFirst) {
  std::vector<RobotStream> robots(2);
  robots[0].robot = "R1";
  robots[0].odometry = {{100, Pose2(1, 0, 0), 0, 0}, {300, Pose2(2, 0, 0), 0, 0}};
  robots[0].scans = {{100, -1.5f, 0.5f, {1.0f, 2.0f, 3.0f}, {}}};
  robots[0].reference = {{100, Pose2(5, 6, 0.5)}};
  robots[1].robot = "R2";
  robots[1].odometry = {{200, Pose2(3, 0, 0), 0, 0}};
  robots[1].time_shift_us = -50;  // --simultaneous: every robot's shift is written
  robots[1].T_body_laser = Pose2(-0.04, 0.0, 0.0);
  const std::string path = ::anchormap::testing::ScratchPath("am_robot_streams.lcmlog");
  WriteCounts counts;
  ASSERT_TRUE(WriteRobotStreams(robots, ImportChannels(), path, &counts).ok());
  EXPECT_EQ(counts.odometry, 3);
  EXPECT_EQ(counts.scans, 1);
  EXPECT_EQ(counts.reference, 1);
  EXPECT_EQ(counts.laser_mounts, 2);
  EXPECT_EQ(counts.clock_shifts, 2);

  LcmLogReader reader;
  ASSERT_TRUE(reader.Open(path).ok());
  std::vector<std::pair<std::string, int64_t>> events;
  while (auto event = reader.Next()) {
    events.emplace_back(event->channel, event->utime);
    if (event->channel == "R1_LASER") {
      const auto scan = DecodeAs<bot_core::planar_lidar_t>(*event);
      ASSERT_TRUE(scan.has_value());
      EXPECT_EQ(scan->nranges, 3);
      EXPECT_EQ(scan->ranges[2], 3.0f);
      EXPECT_EQ(scan->rad0, -1.5f);
      EXPECT_EQ(scan->radstep, 0.5f);
      EXPECT_EQ(scan->nintensities, 0);
    }
    if (event->channel == "R1_REFERENCE") {
      const auto pose = DecodeAs<bot_core::pose_t>(*event);
      ASSERT_TRUE(pose.has_value());
      EXPECT_EQ(pose->pos[0], 5.0);
      EXPECT_NEAR(pose->orientation[3], std::sin(0.25), 1e-15);
    }
    if (event->channel == "R2_LASER_MOUNT") {
      const auto pose = DecodeAs<bot_core::pose_t>(*event);
      ASSERT_TRUE(pose.has_value());
      EXPECT_EQ(pose->pos[0], -0.04);
    }
    if (event->channel == "R2_CLOCK_SHIFT") {
      const auto pose = DecodeAs<bot_core::pose_t>(*event);
      ASSERT_TRUE(pose.has_value());
      EXPECT_EQ(pose->utime, -50);
    }
  }
  // Each robot's laser mount and clock shift come before its first measurement.
  const std::vector<std::pair<std::string, int64_t>> expected = {
      {"R1_LASER_MOUNT", 100}, {"R1_CLOCK_SHIFT", 100}, {"R1_ODOMETRY", 100},
      {"R1_LASER", 100},       {"R1_REFERENCE", 100},   {"R2_LASER_MOUNT", 200},
      {"R2_CLOCK_SHIFT", 200}, {"R2_ODOMETRY", 200},    {"R1_ODOMETRY", 300}};
  EXPECT_EQ(events, expected);
  std::filesystem::remove(path);
}

}  // namespace
}  // namespace anchormap
