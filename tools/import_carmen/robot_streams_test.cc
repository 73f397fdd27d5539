#include "tools/import_carmen/robot_streams.h"

#include <cmath>

#include <gtest/gtest.h>

namespace anchormap {
namespace {

// The robot's true path in the log's frame: a slow arc.
Pose2 PathAt(double t) { return Pose2(0.1 * t, 0.02 * t * t, 0.01 * t); }

// 90 s of log: ODOM every 0.1 s (901 lines), FLASER every 0.5 s (181 lines) whose laser pose
// is the path shifted by 1 m in x (so reference and odometry are distinguishable).
CarmenLogContents MakeLog() {
  CarmenLogContents contents;
  for (int i = 0; i <= 900; ++i) {
    CarmenOdometry odometry;
    odometry.ipc_time_s = 0.1 * i;
    odometry.pose = PathAt(odometry.ipc_time_s);
    odometry.tv_mps = 0.1;
    contents.odometry.push_back(odometry);
  }
  for (int i = 0; i <= 180; ++i) {
    CarmenLaser laser;
    laser.ipc_time_s = 0.5 * i;
    laser.robot_pose = PathAt(laser.ipc_time_s);
    laser.laser_pose = Pose2(laser.robot_pose.x() + 1.0, laser.robot_pose.y(), 0.0);
    laser.start_angle_rad = -M_PI / 2;
    laser.angular_resolution_rad = M_PI / 180;
    laser.ranges_m = {1.0f, 2.0f};
    contents.lasers.push_back(laser);
  }
  return contents;
}

TEST(RobotStreamsTest, WithoutSplitEverythingStaysInTheLogFrame) {
  std::vector<RobotStream> robots;
  SplitSummary summary;
  CarmenImportOptions options;
  ASSERT_TRUE(BuildRobotStreams(MakeLog(), options, &robots, &summary).ok());
  ASSERT_EQ(robots.size(), 1u);
  EXPECT_EQ(robots[0].robot, "R1");
  EXPECT_EQ(robots[0].odometry.size(), 901u);
  EXPECT_EQ(robots[0].scans.size(), 181u);
  EXPECT_EQ(robots[0].reference.size(), 181u);
  EXPECT_EQ(robots[0].odometry[900].utime, 90000000);
  EXPECT_DOUBLE_EQ(robots[0].odometry[900].pose.y(), PathAt(90).y());
  EXPECT_EQ(robots[0].scans[1].utime, 500000);
  EXPECT_FLOAT_EQ(robots[0].scans[1].rad0, static_cast<float>(-M_PI / 2));
  EXPECT_DOUBLE_EQ(robots[0].reference[1].pose.x(), PathAt(0.5).x() + 1.0);
  EXPECT_EQ(summary.odometry_source_used, OdometrySource::kOdomLines);
  EXPECT_DOUBLE_EQ(summary.duration_s(), 90.0);
  EXPECT_EQ(summary.dropped_odometry + summary.dropped_scans, 0);
}

TEST(RobotStreamsTest, SplitMakesIndependentRobotsStartingAtTheOrigin) {
  CarmenImportOptions options;
  options.split = 3;
  options.gap_s = 2.0;
  std::vector<RobotStream> robots;
  SplitSummary summary;
  ASSERT_TRUE(BuildRobotStreams(MakeLog(), options, &robots, &summary).ok());
  ASSERT_EQ(robots.size(), 3u);
  EXPECT_EQ(summary.cut_utimes, (std::vector<int64_t>{30000000, 60000000}));
  EXPECT_EQ(summary.gap_us, 2000000);
  // Dropped: times strictly within 1 s of a cut, 29.1..30.9 and 59.1..60.9 (19 + 19 ODOM),
  // 29.5, 30, 30.5 and 59.5, 60, 60.5 (3 + 3 scans).
  EXPECT_EQ(summary.dropped_odometry, 38);
  EXPECT_EQ(summary.dropped_scans, 6);
  // Pieces: [0, 29], [31, 59], [61, 90] s; 291 + 281 + 291 = 901 - 38 ODOM lines and
  // 59 + 57 + 59 = 181 - 6 scans.
  const int64_t expected_odometry[3] = {291, 281, 291};
  const int64_t expected_scans[3] = {59, 57, 59};
  const double first_time_s[3] = {0.0, 31.0, 61.0};
  for (int k = 0; k < 3; ++k) {
    const RobotStream& robot = robots[k];
    EXPECT_EQ(robot.robot, "R" + std::to_string(k + 1));
    EXPECT_EQ(static_cast<int64_t>(robot.odometry.size()), expected_odometry[k]) << k;
    EXPECT_EQ(static_cast<int64_t>(robot.scans.size()), expected_scans[k]) << k;
    EXPECT_EQ(robot.reference.size(), robot.scans.size());
    // Starts at the origin of its own frame, which is the first pose in the log's frame.
    EXPECT_EQ(robot.odometry.front().utime, std::llround(first_time_s[k] * 1e6));
    EXPECT_NEAR(robot.odometry.front().pose.vector().norm(), 0.0, 1e-12);
    const Pose2 origin = PathAt(first_time_s[k]);
    EXPECT_NEAR(robot.T_log_odometry.x(), origin.x(), 1e-12);
    EXPECT_NEAR(robot.T_log_odometry.y(), origin.y(), 1e-12);
    // A later pose is the same motion re-expressed: origin (+) pose = the log's pose.
    const RobotOdometrySample& last = robot.odometry.back();
    const Pose2 in_log = Compose(robot.T_log_odometry, last.pose);
    const Pose2 truth = PathAt(1e-6 * last.utime);
    EXPECT_NEAR(in_log.x(), truth.x(), 1e-9);
    EXPECT_NEAR(in_log.y(), truth.y(), 1e-9);
    EXPECT_NEAR(in_log.theta(), truth.theta(), 1e-12);
    // The reference stays in the log's frame.
    EXPECT_NEAR(robot.reference.front().pose.x(),
                PathAt(1e-6 * robot.reference.front().utime).x() + 1.0, 1e-12);
  }
}

TEST(RobotStreamsTest, SimultaneousShiftsPiecesToStartTogetherAndKeepsTheShift) {
  CarmenImportOptions options;
  options.split = 3;
  options.gap_s = 2.0;
  options.simultaneous = true;
  std::vector<RobotStream> robots;
  SplitSummary summary;
  const CarmenLogContents log = MakeLog();
  ASSERT_TRUE(BuildRobotStreams(log, options, &robots, &summary).ok());
  ASSERT_EQ(robots.size(), 3u);
  // Pieces began at 0, 31 and 61 s of the log: all start at 0 now.
  const int64_t expected_shift[3] = {0, -31000000, -61000000};
  for (int k = 0; k < 3; ++k) {
    const RobotStream& robot = robots[k];
    EXPECT_EQ(robot.time_shift_us, expected_shift[k]) << k;
    EXPECT_EQ(robot.odometry.front().utime, 0) << k;
    // Log time = output time - shift: the odometry, scans and reference moved together.
    const RobotOdometrySample& last = robot.odometry.back();
    const Pose2 truth = PathAt(1e-6 * static_cast<double>(last.utime - robot.time_shift_us));
    EXPECT_NEAR(Compose(robot.T_log_odometry, last.pose).y(), truth.y(), 1e-9);
    const StampedPose2& reference = robot.reference.back();
    EXPECT_NEAR(reference.pose.x(),
                PathAt(1e-6 * static_cast<double>(reference.utime - robot.time_shift_us)).x() + 1.0,
                1e-12);
    EXPECT_EQ(robot.scans.back().utime, reference.utime);
    // Every piece carries the log's laser mounting.
    EXPECT_NEAR(PoseError(robot.T_body_laser, EstimateLaserMounting(log)).norm(), 0.0, 1e-15);
  }
  options.split = 1;
  EXPECT_FALSE(options.Validate().ok());  // nothing to shift
}

TEST(RobotStreamsTest, DefaultGapIsTwoPercentOfTheDuration) {
  CarmenImportOptions options;
  options.split = 2;
  std::vector<RobotStream> robots;
  SplitSummary summary;
  ASSERT_TRUE(BuildRobotStreams(MakeLog(), options, &robots, &summary).ok());
  EXPECT_EQ(summary.gap_us, 1800000);  // 2% of 90 s
  // Cut at 45 s; dropped: 44.2..45.8 (17 ODOM lines) and 44.5, 45, 45.5 (3 scans).
  EXPECT_EQ(summary.dropped_odometry, 17);
  EXPECT_EQ(summary.dropped_scans, 3);
}

TEST(RobotStreamsTest, SortsOdometryByTimeAndKeepsFileOrderForTies) {
  CarmenLogContents contents = MakeLog();
  std::swap(contents.odometry[10], contents.odometry[11]);  // 1.1 s logged before 1.0 s
  std::vector<RobotStream> robots;
  SplitSummary summary;
  ASSERT_TRUE(BuildRobotStreams(contents, CarmenImportOptions(), &robots, &summary).ok());
  EXPECT_EQ(summary.odometry_source_used, OdometrySource::kOdomLines);
  for (size_t i = 1; i < robots[0].odometry.size(); ++i) {
    ASSERT_LT(robots[0].odometry[i - 1].utime, robots[0].odometry[i].utime) << i;
  }
  EXPECT_TRUE(robots[0].time_repairs.empty());
}

TEST(RobotStreamsTest, LaserTimesSteppingBackAreRepairedInFileOrder) {
  // Like the Intel log: lines 3 and 4 (at 1.5 s and 2.0 s) stamped 1.4 s and 1.1 s earlier
  // although their poses continue the motion; they are spread evenly between 1.0 s and 2.5 s.
  CarmenLogContents contents = MakeLog();
  contents.lasers[3].ipc_time_s = 0.1;
  contents.lasers[4].ipc_time_s = 0.9;
  int64_t repaired = 0;
  const std::vector<int64_t> utimes = RepairedLaserTimes(contents.lasers, &repaired);
  EXPECT_EQ(repaired, 2);
  ASSERT_EQ(utimes.size(), 181u);
  EXPECT_EQ(utimes[2], 1'000'000);
  EXPECT_EQ(utimes[3], 1'500'000);
  EXPECT_EQ(utimes[4], 2'000'000);
  EXPECT_EQ(utimes[5], 2'500'000);

  // The streams: scans in file order at the repaired times, odometry from the laser lines (the
  // ODOM lines' stamps cannot be ordered against them), the repairs recorded for eval.
  std::vector<RobotStream> robots;
  SplitSummary summary;
  ASSERT_TRUE(BuildRobotStreams(contents, CarmenImportOptions(), &robots, &summary).ok());
  EXPECT_EQ(summary.repaired_scan_times, 2);
  EXPECT_EQ(summary.odometry_source_used, OdometrySource::kLaserLines);
  ASSERT_EQ(robots[0].odometry.size(), 181u);
  EXPECT_EQ(robots[0].odometry[3].utime, 1'500'000);
  EXPECT_DOUBLE_EQ(robots[0].odometry[3].pose.x(), PathAt(1.5).x());
  EXPECT_EQ(robots[0].scans[4].utime, 2'000'000);
  EXPECT_NEAR(robots[0].reference[4].pose.x(), PathAt(2.0).x() + 1.0, 1e-12);
  ASSERT_EQ(robots[0].time_repairs.size(), 2u);
  EXPECT_EQ(robots[0].time_repairs[0].utime, 1'500'000);
  EXPECT_EQ(robots[0].time_repairs[0].stamped_minus_repaired_us, -1'400'000);
  EXPECT_EQ(robots[0].time_repairs[1].stamped_minus_repaired_us, -1'100'000);

  // A run to the end of the log: 1 us apart after the last good time.
  contents.lasers[180].ipc_time_s = 1.0;
  RepairedLaserTimes(contents.lasers, &repaired);
  EXPECT_EQ(repaired, 3);
  EXPECT_EQ(RepairedLaserTimes(contents.lasers, &repaired)[180], 89'500'001);
}

TEST(RobotStreamsTest, OdometryFromLaserLinesWhenTheLogHasNoOdom) {
  CarmenLogContents contents = MakeLog();
  contents.odometry.clear();
  std::vector<RobotStream> robots;
  SplitSummary summary;
  ASSERT_TRUE(BuildRobotStreams(contents, CarmenImportOptions(), &robots, &summary).ok());
  EXPECT_EQ(summary.odometry_source_used, OdometrySource::kLaserLines);
  ASSERT_EQ(robots[0].odometry.size(), 181u);
  EXPECT_DOUBLE_EQ(robots[0].odometry[2].pose.x(), PathAt(1.0).x());

  CarmenImportOptions from_odom;
  from_odom.odometry_source = OdometrySource::kOdomLines;
  EXPECT_EQ(BuildRobotStreams(contents, from_odom, &robots, &summary).message(),
            "the log has no ODOM lines (try the laser lines' odometry)");
}

TEST(RobotStreamsTest, GapTooLargeIsAnErrorNamingThePiece) {
  CarmenImportOptions options;
  options.split = 3;
  options.gap_s = 40.0;
  std::vector<RobotStream> robots;
  SplitSummary summary;
  EXPECT_EQ(BuildRobotStreams(MakeLog(), options, &robots, &summary).message(),
            "piece 2 (R2) has no odometry between 30.000 s and 60.000 s: gap too large for "
            "this log?");
}

TEST(CarmenImportOptionsTest, ValidateNamesTheField) {
  CarmenImportOptions options;
  EXPECT_TRUE(options.Validate().ok());
  options.robot = "r1";
  EXPECT_EQ(options.Validate().message(), "robot: 'r1' is not an upper-case name like R1");
  options.robot = "R1";
  options.split = 0;
  EXPECT_EQ(options.Validate().message(), "split: 0 is not in [1, 100]");
  options.split = 3;
  options.gap_fraction = 0.6;
  EXPECT_FALSE(options.Validate().ok());
}

TEST(PieceRobotNamesTest, CountsOnFromTheGivenName) {
  EXPECT_EQ(PieceRobotNames("R1", 1), (std::vector<std::string>{"R1"}));
  EXPECT_EQ(PieceRobotNames("R1", 3), (std::vector<std::string>{"R1", "R2", "R3"}));
  EXPECT_EQ(PieceRobotNames("R4", 2), (std::vector<std::string>{"R4", "R5"}));
  EXPECT_EQ(PieceRobotNames("ALPHA", 2), (std::vector<std::string>{"ALPHA1", "ALPHA2"}));
}

}  // namespace
}  // namespace anchormap
