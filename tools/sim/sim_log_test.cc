#include "tools/sim/sim_log.h"

#include <cmath>
#include <filesystem>
#include <map>

#include <gtest/gtest.h>

#include "bot_core/planar_lidar_t.hpp"
#include "common/bus/lcm_log.h"
#include "tests/testing/file_contents.h"
#include "tests/testing/scratch.h"

namespace anchormap::sim {
namespace {

using ::anchormap::testing::ScratchPath;

SimOptions ShortRun(uint64_t seed) {
  SimOptions options;
  options.robots = 3;
  options.seed = seed;
  options.duration_s = 20.0;
  return options;
}

TEST(SimLogTest, SameSeedGivesIdenticalBytesAndOtherSeedsDiffer) {
  const std::string a = ScratchPath("sim_a.lcmlog");
  const std::string b = ScratchPath("sim_b.lcmlog");
  const std::string c = ScratchPath("sim_c.lcmlog");
  ASSERT_TRUE(WriteSimulationLog(ShortRun(7), a, nullptr).ok());
  ASSERT_TRUE(WriteSimulationLog(ShortRun(7), b, nullptr).ok());
  ASSERT_TRUE(WriteSimulationLog(ShortRun(8), c, nullptr).ok());
  const std::string bytes_a = ::anchormap::testing::FileContents(a);
  EXPECT_GT(bytes_a.size(), 1000000u);
  EXPECT_TRUE(bytes_a == ::anchormap::testing::FileContents(b));
  EXPECT_FALSE(bytes_a == ::anchormap::testing::FileContents(c));
}

TEST(SimLogTest, ChangingTheLaserDoesNotChangeTheOdometry) {
  // Separate random streams: the beam count changes the scans only.
  SimOptions options = ShortRun(3);
  SimOptions other = options;
  other.laser.beams = 181;
  const std::string a = ScratchPath("streams_a.lcmlog");
  const std::string b = ScratchPath("streams_b.lcmlog");
  ASSERT_TRUE(WriteSimulationLog(options, a, nullptr).ok());
  ASSERT_TRUE(WriteSimulationLog(other, b, nullptr).ok());
  LcmLogReader ra, rb;
  ASSERT_TRUE(ra.Open(a).ok());
  ASSERT_TRUE(rb.Open(b).ok());
  std::vector<std::vector<uint8_t>> odometry_a, odometry_b;
  while (auto e = ra.Next()) {
    if (e->channel == "R2_ODOMETRY") odometry_a.push_back(e->data);
  }
  while (auto e = rb.Next()) {
    if (e->channel == "R2_ODOMETRY") odometry_b.push_back(e->data);
  }
  ASSERT_EQ(odometry_a.size(), 1001u);
  EXPECT_EQ(odometry_a, odometry_b);
}

TEST(SimLogTest, LogHoldsTheContractChannelsAtTheirRates) {
  const std::string path = ScratchPath("sim_channels.lcmlog");
  SimOptions options = ShortRun(1);
  options.duration_s = 60.0;
  SimSummary summary;
  ASSERT_TRUE(WriteSimulationLog(options, path, &summary).ok());
  LcmLogReader reader;
  ASSERT_TRUE(reader.Open(path).ok());
  std::map<std::string, int> counts;
  int64_t last_utime = 0;
  std::map<std::string, std::map<int64_t, Pose2>> truth;  // robot -> utime -> pose
  std::vector<anchormap::encounter_t> encounters;
  std::vector<std::string> encounter_channels;
  int64_t returns = 0;
  int64_t beams = 0;
  while (auto event = reader.Next()) {
    ++counts[event->channel];
    EXPECT_GE(event->utime, last_utime);
    last_utime = event->utime;
    const std::string robot = event->channel.substr(0, event->channel.find('_'));
    if (event->channel.find("_ODOMETRY") != std::string::npos) {
      const auto pose = DecodeAs<bot_core::pose_t>(*event);
      ASSERT_TRUE(pose);
      EXPECT_EQ(pose->utime, event->utime);
      if (event->utime == kSimEpochUtime) {
        // Every robot's odometry starts at its own origin.
        EXPECT_EQ(pose->pos[0], 0.0);
        EXPECT_EQ(pose->pos[1], 0.0);
        EXPECT_EQ(pose->orientation[0], 1.0);
      }
      const double norm = std::hypot(pose->orientation[0], pose->orientation[3]);
      EXPECT_NEAR(norm, 1.0, 1e-12);
    } else if (event->channel.find("_LASER") != std::string::npos) {
      const auto scan = DecodeAs<bot_core::planar_lidar_t>(*event);
      ASSERT_TRUE(scan);
      EXPECT_EQ(scan->nranges, 361);
      EXPECT_NEAR(scan->radstep, kPi / 180.0, 1e-7);
      // Inside the office most beams hit a wall within 30 m; the others (long views
      // through doors) read exactly the maximum range.
      for (float r : scan->ranges) {
        EXPECT_LE(r, 30.0f);
        EXPECT_GT(r, 0.3f);  // robots keep 0.45 m from walls
        returns += r < 30.0f ? 1 : 0;
        ++beams;
      }
    } else if (event->channel.find("_GROUND_TRUTH") != std::string::npos) {
      const auto pose = DecodeAs<bot_core::pose_t>(*event);
      ASSERT_TRUE(pose);
      truth[robot][pose->utime] = FromPoseMessage(*pose);
    } else if (event->channel.find("_ENCOUNTER") != std::string::npos) {
      const auto encounter = DecodeAs<anchormap::encounter_t>(*event);
      ASSERT_TRUE(encounter);
      encounters.push_back(*encounter);
      encounter_channels.push_back(robot);
    }
  }
  // 60 s: 3001 odometry messages (50 Hz, both ends included), 601 scans and truths.
  for (const std::string robot : {"R1", "R2", "R3"}) {
    EXPECT_EQ(counts[robot + "_ODOMETRY"], 3001) << robot;
    EXPECT_EQ(counts[robot + "_LASER"], 601) << robot;
    EXPECT_EQ(counts[robot + "_GROUND_TRUTH"], 601) << robot;
  }
  EXPECT_EQ(summary.scans, 3 * 601);
  EXPECT_GT(static_cast<double>(returns) / beams, 0.95);
  EXPECT_EQ(static_cast<size_t>(summary.encounters), encounters.size());
  ASSERT_FALSE(encounters.empty());
  for (size_t i = 0; i < encounters.size(); ++i) {
    const anchormap::encounter_t& e = encounters[i];
    EXPECT_EQ(e.observer, encounter_channels[i]);
    EXPECT_EQ(e.observer_trajectory_id, 0);
    EXPECT_NE(e.observer, e.observed);
    // The measurement agrees with the ground truth at the same time within 5 sigma.
    const Pose2 truth_relative =
        Between(truth[e.observer].at(e.utime), truth[e.observed].at(e.utime));
    EXPECT_NEAR(e.relative_pose[0], truth_relative.x(), 5 * std::sqrt(e.covariance[0]));
    EXPECT_NEAR(e.relative_pose[1], truth_relative.y(), 5 * std::sqrt(e.covariance[4]));
    EXPECT_NEAR(AngleDifference(e.relative_pose[2], truth_relative.theta()), 0.0,
                5 * std::sqrt(e.covariance[8]));
    EXPECT_LE(std::hypot(truth_relative.x(), truth_relative.y()), 5.0 + 1e-9);
  }
}

TEST(SimLogTest, RobotsMoveAndOdometryDriftsModestly) {
  SimOptions options = ShortRun(4);
  options.duration_s = 120.0;
  SimSummary summary;
  const std::string path = ScratchPath("sim_drift.lcmlog");
  ASSERT_TRUE(WriteSimulationLog(options, path, &summary).ok());
  for (double d : summary.distance_m) {
    EXPECT_GT(d, 30.0);  // at 0.8 m/s with turns and pauses
    EXPECT_LT(d, 96.1);  // never faster than the speed
  }
  EXPECT_EQ(summary.planning_failures, 0);
}

TEST(SimLogTest, HundredRobotsGiveAValidLog) {
  SimOptions options;
  options.robots = 100;
  options.duration_s = 2.0;
  options.laser.beams = 91;
  SimSummary summary;
  const std::string path = ScratchPath("sim_100.lcmlog");
  ASSERT_TRUE(WriteSimulationLog(options, path, &summary).ok());
  EXPECT_EQ(summary.robots, 100);
  EXPECT_EQ(summary.scans, 100 * 21);
  EXPECT_GT(summary.world_max.x() - summary.world_min.x(), 150.0);  // 5 x 4 office tiles
  LcmLogReader reader;
  ASSERT_TRUE(reader.Open(path).ok());
  int64_t events = 0;
  std::map<std::string, int> truth_per_robot;
  while (auto event = reader.Next()) {
    ++events;
    if (event->channel.find("_GROUND_TRUTH") != std::string::npos)
      ++truth_per_robot[event->channel];
  }
  EXPECT_EQ(events, summary.events);
  EXPECT_EQ(truth_per_robot.size(), 100u);
  EXPECT_EQ(truth_per_robot["R100_GROUND_TRUTH"], 21);
}

TEST(SimLogTest, MissingPgmWorldFailsCleanly) {
  SimOptions options = ShortRun(1);
  options.world = "/nonexistent/world.pgm";
  const Status status = WriteSimulationLog(options, ScratchPath("never.lcmlog"), nullptr);
  EXPECT_FALSE(status.ok());
  EXPECT_NE(status.message().find("world.pgm"), std::string::npos);
}

TEST(SimLogTest, PoseMessageRoundTrip) {
  const bot_core::pose_t message = ToPoseMessage(5, Pose2(1.0, -2.0, 2.5), {1.0, 0.0, 0.3});
  EXPECT_NEAR(message.orientation[0], std::cos(1.25), 1e-15);
  EXPECT_NEAR(message.orientation[3], std::sin(1.25), 1e-15);
  EXPECT_NEAR(message.vel[0], std::cos(2.5), 1e-15);  // forward velocity in the pose's frame
  EXPECT_NEAR(message.vel[1], std::sin(2.5), 1e-15);
  EXPECT_EQ(message.rotation_rate[2], 0.3);
  const Pose2 back = FromPoseMessage(message);
  EXPECT_NEAR(back.x(), 1.0, 1e-15);
  EXPECT_NEAR(back.theta(), 2.5, 1e-12);
}

}  // namespace
}  // namespace anchormap::sim
