#include "common/io/trajectory_file.h"
#include "tests/testing/scratch.h"

#include <cmath>
#include <filesystem>
#include <fstream>

#include <gtest/gtest.h>

namespace anchormap {
namespace {

using ::anchormap::testing::ScratchPath;

TEST(TrajectoryFileTest, ParsesYawOnlyQuaternion) {
  StampedPose2 pose;
  // Yaw 90 degrees: (qz, qw) = (sin 45, cos 45).
  ASSERT_TRUE(ParseTrajectoryLine("976052857.337530 1.5 -2 0 0 0 0.7071067811865476 "
                                  "0.7071067811865476",
                                  &pose)
                  .ok());
  EXPECT_EQ(pose.utime, 976052857337530);
  EXPECT_DOUBLE_EQ(pose.pose.x(), 1.5);
  EXPECT_DOUBLE_EQ(pose.pose.y(), -2.0);
  EXPECT_NEAR(pose.pose.theta(), M_PI / 2, 1e-12);
  // Commas separate too (CSV flavour).
  ASSERT_TRUE(ParseTrajectoryLine("1.0,2,3,0,0,0,-1,0", &pose).ok());
  EXPECT_NEAR(std::abs(pose.pose.theta()), M_PI, 1e-12);
}

TEST(TrajectoryFileTest, RejectsMalformedLinesWithReasons) {
  StampedPose2 pose;
  EXPECT_EQ(ParseTrajectoryLine("1 2 3", &pose).message(),
            "expected 8 fields (timestamp x y z qx qy qz qw), found 3");
  EXPECT_EQ(ParseTrajectoryLine("1 2 abc 0 0 0 0 1", &pose).message(),
            "field y 'abc' is not a finite number");
  EXPECT_EQ(ParseTrajectoryLine("1 2 3 0 0 0 0 2", &pose).message(),
            "quaternion norm 2.000000 is not 1");
}

TEST(TrajectoryFileTest, WriteThenReadRoundTripsToMicrosecondsAndTenDigits) {
  StampedTrajectory poses = {{976052857337530, Pose2(1.25, -3.5, 3.0)},
                             {976052857537531, Pose2(-1e-3, 12345.678, -2.5)},
                             {-500000, Pose2(0, 0, M_PI)}};
  const std::string path = ScratchPath("anchormap_trajectory_file_test.txt");
  ASSERT_TRUE(WriteTrajectoryFile(path, poses, "test").ok());
  StampedTrajectory read;
  ASSERT_TRUE(ReadTrajectoryFile(path, &read).ok());
  ASSERT_EQ(read.size(), poses.size());
  for (size_t i = 0; i < poses.size(); ++i) {
    EXPECT_EQ(read[i].utime, poses[i].utime);
    EXPECT_NEAR(read[i].pose.x(), poses[i].pose.x(), 1e-9 * (1 + std::abs(poses[i].pose.x())));
    EXPECT_NEAR(read[i].pose.y(), poses[i].pose.y(), 1e-9 * (1 + std::abs(poses[i].pose.y())));
    EXPECT_NEAR(std::abs(AngleDifference(read[i].pose.theta(), poses[i].pose.theta())), 0.0, 1e-9);
  }
  EXPECT_EQ(FormatTrajectoryLine(poses[2]).substr(0, 10), "-0.500000 ");
  std::filesystem::remove(path);
}

TEST(TrajectoryFileTest, ReadErrorsNameFileAndLine) {
  const std::string path = ScratchPath("anchormap_trajectory_file_bad.txt");
  {
    std::ofstream out(path);
    out << "# header\n\n1 0 0 0 0 0 0 1\n2 0 0 0 0 0 0\n";
  }
  StampedTrajectory read;
  const Status status = ReadTrajectoryFile(path, &read);
  EXPECT_EQ(status.message(),
            path + ":4: expected 8 fields (timestamp x y z qx qy qz qw), found 7");
  EXPECT_FALSE(ReadTrajectoryFile("/nonexistent/x.txt", &read).ok());
  std::filesystem::remove(path);
}

}  // namespace
}  // namespace anchormap
