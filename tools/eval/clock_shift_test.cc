#include "tools/eval/clock_shift.h"

#include <filesystem>

#include <unistd.h>

#include <gtest/gtest.h>

#include "bot_core/pose_t.hpp"
#include "common/bus/lcm_log.h"
#include "tests/testing/scratch.h"

namespace anchormap {
namespace {

bot_core::pose_t PoseMessage(int64_t utime) {
  bot_core::pose_t message{};
  message.utime = utime;
  message.orientation[0] = 1.0;
  return message;
}

TEST(ClockShiftTest, ReadsShiftsAndMovesEstimateAndOdometryBack) {
  const std::string path = ::anchormap::testing::ScratchPath("am_clock_shift.lcmlog");
  {
    LcmLogWriter writer;
    ASSERT_TRUE(writer.Open(path).ok());
    ASSERT_TRUE(writer.Write("R1_CLOCK_SHIFT", 100, PoseMessage(0)).ok());
    ASSERT_TRUE(writer.Write("R2_CLOCK_SHIFT", 100, PoseMessage(-5'000'000)).ok());
    ASSERT_TRUE(writer.Write("R2_ODOMETRY", 100, PoseMessage(100)).ok());
    writer.Close();
  }
  std::map<std::string, int64_t> shifts;
  ASSERT_TRUE(ReadClockShifts(path, &shifts).ok());
  EXPECT_EQ(shifts, (std::map<std::string, int64_t>{{"R1", 0}, {"R2", -5'000'000}}));

  MapEstimate estimate;
  estimate.trajectories.resize(3);
  estimate.trajectories[0].robot = "R1";
  estimate.trajectories[1].robot = "R2";
  estimate.trajectories[2].robot = "R3";  // no shift recorded: left alone
  for (EstimatedTrajectory& t : estimate.trajectories) t.poses = {{100, Pose2()}, {200, Pose2()}};
  std::map<std::string, StampedTrajectory> odometry = {{"R2", {{150, Pose2()}}}};
  ShiftToLogClock(shifts, &estimate, &odometry);
  EXPECT_EQ(estimate.trajectories[0].poses[1].utime, 200);
  EXPECT_EQ(estimate.trajectories[1].poses[0].utime, 5'000'100);  // log time = shifted - shift
  EXPECT_EQ(estimate.trajectories[1].poses[1].utime, 5'000'200);
  EXPECT_EQ(estimate.trajectories[2].poses[0].utime, 100);
  EXPECT_EQ(odometry["R2"][0].utime, 5'000'150);

  // Two different shifts for one robot are an error.
  {
    LcmLogWriter writer;
    ASSERT_TRUE(writer.Open(path).ok());
    ASSERT_TRUE(writer.Write("R1_CLOCK_SHIFT", 100, PoseMessage(0)).ok());
    ASSERT_TRUE(writer.Write("R1_CLOCK_SHIFT", 200, PoseMessage(7)).ok());
    writer.Close();
  }
  EXPECT_FALSE(ReadClockShifts(path, &shifts).ok());
  std::filesystem::remove(path);
}

TEST(ClockShiftTest, TimeRepairsMoveTheRelationsOfReTimedScans) {
  const std::string path = ::anchormap::testing::ScratchPath("am_time_repair.lcmlog");
  {
    LcmLogWriter writer;
    ASSERT_TRUE(writer.Open(path).ok());
    ASSERT_TRUE(writer.Write("R2_CLOCK_SHIFT", 100, PoseMessage(-5'000'000)).ok());
    bot_core::pose_t repair = PoseMessage(1'500'000);  // R1: stamped 0.1 s, repaired 1.5 s
    repair.pos[0] = -1'400'000.0;
    ASSERT_TRUE(writer.Write("R1_TIME_REPAIR", 1'500'000, repair).ok());
    repair = PoseMessage(2'000'000);  // R2, shifted by -5 s: stamped 6.5 s, repaired 7.0 s
    repair.pos[0] = -500'000.0;
    ASSERT_TRUE(writer.Write("R2_TIME_REPAIR", 2'000'000, repair).ok());
    writer.Close();
  }
  std::map<std::string, int64_t> shifts;
  ASSERT_TRUE(ReadClockShifts(path, &shifts).ok());
  std::map<int64_t, int64_t> repaired_by_stamp;
  ASSERT_TRUE(ReadTimeRepairs(path, shifts, &repaired_by_stamp).ok());
  EXPECT_EQ(repaired_by_stamp,
            (std::map<int64_t, int64_t>{{100'000, 1'500'000}, {6'500'000, 7'000'000}}));
  std::vector<Relation> relations = {
      {0.1, 6.5, Pose2()}, {0.100001, 3.0, Pose2()}, {6.5, 0.1, Pose2()}};
  EXPECT_EQ(ApplyTimeRepairs(repaired_by_stamp, &relations), 4);
  EXPECT_DOUBLE_EQ(relations[0].t1_s, 1.5);
  EXPECT_DOUBLE_EQ(relations[0].t2_s, 7.0);
  EXPECT_DOUBLE_EQ(relations[1].t1_s, 0.100001);  // another scan: not moved
  EXPECT_DOUBLE_EQ(relations[2].t2_s, 1.5);
  std::filesystem::remove(path);
}

}  // namespace
}  // namespace anchormap
