#include "agent/agent.h"

#include <gtest/gtest.h>

namespace anchormap {
namespace {

AgentOptions TestOptions() {
  AgentOptions options;
  options.robot = "R1";
  options.trajectory_id = 4242;
  options.keyframer.max_distance_m = 0.45;  // scans every 0.1 m: keyframes every 0.5 m
  options.keyframer.max_angle_rad = 0.5;
  options.keyframer.max_interval_s = 0;
  options.sensor_x_m = 0.1;
  EXPECT_TRUE(options.Validate().ok());
  return options;
}

LaserScan Scan(int64_t utime) {
  LaserScan scan;
  scan.utime = utime;
  scan.rad0 = -1.0f;
  scan.radstep = 0.5f;
  scan.ranges = {1, 2, 3, 4, 5};
  return scan;
}

// Drives straight along x at 1 m/s: odometry at 50 Hz, a scan at 10 Hz (5 ms after the
// odometry reading before it), for `seconds`.
AgentOutput DriveStraight(Agent* agent, double seconds) {
  AgentOutput out;
  for (int64_t t = 0; t <= static_cast<int64_t>(seconds * 1e6); t += 20'000) {
    EXPECT_TRUE(agent->OnOdometry({t, Pose2(1e-6 * t, 0, 0)}, &out).ok());
    if (t % 100'000 == 20'000) {
      EXPECT_TRUE(agent->OnScan(Scan(t - 15'000), &out).ok());
    }
  }
  return out;
}

TEST(AgentTest, KeyframesEveryHalfMetreWithInterpolatedPosesAndScaledCovariance) {
  Agent agent(TestOptions());
  const AgentOutput out = DriveStraight(&agent, 3.0);
  // Scans at 0.005, 0.105, ... s; keyframes where 0.5 m have been covered since the last.
  ASSERT_EQ(out.keyframes.size(), 6u);
  for (size_t i = 0; i < out.keyframes.size(); ++i) {
    const Keyframe& k = out.keyframes[i];
    EXPECT_EQ(k.robot, "R1");
    EXPECT_EQ(k.trajectory_id, 4242);
    EXPECT_EQ(k.seq, static_cast<int32_t>(i));
    EXPECT_EQ(k.utime, static_cast<int64_t>(i) * 500'000 + 5'000);
    EXPECT_NEAR(k.T_local_pose.x(), 0.5 * i + 0.005, 1e-12);  // interpolated at the scan time
    EXPECT_EQ(k.scan.ranges.size(), 5u);
    EXPECT_DOUBLE_EQ(k.scan.T_body_sensor.x(), 0.1);
    EXPECT_FLOAT_EQ(k.scan.max_range, 30.0f);
  }
  EXPECT_TRUE(out.keyframes[0].T_previous_this_covariance.isIdentity());
  EXPECT_NEAR(out.keyframes[1].T_previous_this.x(), 0.5, 1e-12);
  // sigma_xy = 0.01 + 0.05 * 0.5, sigma_theta = 0.005 + 0.02 * 0.5.
  EXPECT_NEAR(out.keyframes[1].T_previous_this_covariance(0, 0), 0.035 * 0.035, 1e-15);
  EXPECT_NEAR(out.keyframes[1].T_previous_this_covariance(2, 2), 0.015 * 0.015, 1e-15);
  EXPECT_EQ(out.keyframes[1].T_previous_this_covariance(0, 1), 0.0);
  EXPECT_EQ(agent.stats().scans, 30);
}

TEST(AgentTest, ScanAheadOfOdometryWaitsForIt) {
  Agent agent(TestOptions());
  AgentOutput out;
  ASSERT_TRUE(agent.OnOdometry({0, Pose2()}, &out).ok());
  ASSERT_TRUE(agent.OnScan(Scan(10'000), &out).ok());  // odometry only reaches t = 0
  EXPECT_TRUE(out.keyframes.empty());
  EXPECT_EQ(agent.pending_scans(), 1u);
  ASSERT_TRUE(agent.OnOdometry({20'000, Pose2(0.02, 0, 0.2)}, &out).ok());
  ASSERT_EQ(out.keyframes.size(), 1u);
  EXPECT_NEAR(out.keyframes[0].T_local_pose.x(), 0.01, 1e-12);
  EXPECT_NEAR(out.keyframes[0].T_local_pose.theta(), 0.1, 1e-12);
  EXPECT_EQ(agent.pending_scans(), 0u);
}

TEST(AgentTest, RefusesOutOfOrderScansAndScansBeforeTheOdometryHistory) {
  Agent agent(TestOptions());
  AgentOutput out;
  ASSERT_TRUE(agent.OnOdometry({1'000'000, Pose2()}, &out).ok());
  EXPECT_EQ(agent.OnScan(Scan(500'000), &out).code(), ErrorCode::kNoOdometry);
  ASSERT_TRUE(agent.OnOdometry({1'020'000, Pose2()}, &out).ok());
  ASSERT_TRUE(agent.OnScan(Scan(1'010'000), &out).ok());
  EXPECT_EQ(agent.OnScan(Scan(1'010'000), &out).code(), ErrorCode::kOutOfOrder);
  EXPECT_EQ(agent.OnScan(Scan(1'000'000), &out).code(), ErrorCode::kOutOfOrder);
  EXPECT_EQ(agent.OnOdometry({1'020'000, Pose2()}, &out).code(), ErrorCode::kOutOfOrder);
}

TEST(AgentTest, PendingScansAreBounded) {
  AgentOptions options = TestOptions();
  options.max_pending_scans = 3;
  Agent agent(options);
  AgentOutput out;
  for (int i = 1; i <= 5; ++i) ASSERT_TRUE(agent.OnScan(Scan(i * 100'000), &out).ok());
  EXPECT_EQ(agent.pending_scans(), 3u);
  ASSERT_EQ(out.late_rejections.size(), 2u);
  EXPECT_EQ(out.late_rejections[0].code(), ErrorCode::kQueueFull);
}

TEST(AgentTest, RelaysEncounterWithTrajectoryIdAndForcesAKeyframe) {
  Agent agent(TestOptions());
  AgentOutput out = DriveStraight(&agent, 1.0);  // keyframes at 0.005 and 0.505 s
  ASSERT_EQ(out.keyframes.size(), 2u);
  Encounter encounter;
  encounter.utime = 1'150'000;
  encounter.observer = "R1";
  encounter.observed = "R2";
  AgentOutput relay;
  ASSERT_TRUE(agent.OnEncounter(encounter, &relay).ok());
  ASSERT_EQ(relay.encounters.size(), 1u);
  EXPECT_EQ(relay.encounters[0].observer_trajectory_id, 4242);
  EXPECT_EQ(relay.encounters[0].observed, "R2");

  // Continue driving: a keyframe at the first scan at or after 1.15 s (1.205 s), although
  // only 0.7 m... the distance rule alone would give 1.005 and 1.505 s.
  AgentOutput more;
  for (int64_t t = 1'020'000; t <= 1'300'000; t += 20'000) {
    ASSERT_TRUE(agent.OnOdometry({t, Pose2(1e-6 * t, 0, 0)}, &more).ok());
    if (t % 100'000 == 20'000) {
      ASSERT_TRUE(agent.OnScan(Scan(t - 15'000), &more).ok());
    }
  }
  ASSERT_EQ(more.keyframes.size(), 2u);
  EXPECT_EQ(more.keyframes[0].utime, 1'005'000);  // distance rule
  EXPECT_EQ(more.keyframes[1].utime, 1'205'000);  // forced by the encounter
  EXPECT_EQ(agent.stats().forced_keyframes, 1);

  encounter.observer = "R3";
  EXPECT_EQ(agent.OnEncounter(encounter, &relay).code(), ErrorCode::kWrongRobot);
}

TEST(AgentTest, BeingObservedAlsoForcesAKeyframe) {
  Agent agent(TestOptions());
  AgentOutput out;
  ASSERT_TRUE(agent.OnOdometry({0, Pose2()}, &out).ok());
  ASSERT_TRUE(agent.OnOdometry({100'000, Pose2()}, &out).ok());
  ASSERT_TRUE(agent.OnScan(Scan(10'000), &out).ok());  // first keyframe
  Encounter seen;
  seen.utime = 40'000;
  seen.observer = "R2";
  seen.observed = "R1";
  agent.OnRelayedEncounter(seen);
  ASSERT_TRUE(agent.OnScan(Scan(30'000), &out).ok());  // before the encounter: no keyframe
  ASSERT_TRUE(agent.OnScan(Scan(50'000), &out).ok());  // first scan after it: keyframe
  ASSERT_EQ(out.keyframes.size(), 2u);
  EXPECT_EQ(out.keyframes[1].utime, 50'000);
  EXPECT_EQ(out.keyframes[1].seq, 1);
}

TEST(AgentTest, NoiseModelGrowsWithTurnAndDistance) {
  const MotionNoise noise = DefaultOdometryNoise();
  const Eigen::Matrix3d still = noise.Covariance(Pose2());
  EXPECT_NEAR(still(0, 0), 1e-4, 1e-18);
  EXPECT_NEAR(still(2, 2), 2.5e-5, 1e-18);
  const Eigen::Matrix3d turn = noise.Covariance(Pose2(0, 0, 1.0));
  EXPECT_NEAR(turn(2, 2), 0.055 * 0.055, 1e-15);
  EXPECT_NEAR(turn(0, 0), 1e-4, 1e-18);
}

}  // namespace
}  // namespace anchormap
