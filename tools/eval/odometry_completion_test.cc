#include "tools/eval/odometry_completion.h"

#include <cmath>

#include <gtest/gtest.h>

namespace anchormap {
namespace {

TEST(InterpolateOdometryTest, LinearInPositionShortArcInAngle) {
  const StampedTrajectory odometry = {{0, Pose2(0, 0, 3.0)}, {100, Pose2(1, 2, -3.0)}};
  const auto mid = InterpolateOdometry(odometry, 25, 1000);
  ASSERT_TRUE(mid.has_value());
  EXPECT_DOUBLE_EQ(mid->x(), 0.25);
  EXPECT_DOUBLE_EQ(mid->y(), 0.5);
  // From 3.0 to -3.0 the short way is +(2 pi - 6) through pi: a quarter of it.
  EXPECT_NEAR(mid->theta(), WrapAngle(3.0 + 0.25 * (2 * M_PI - 6.0)), 1e-12);
  EXPECT_EQ(InterpolateOdometry(odometry, 100, 1000)->x(), 1.0);
  EXPECT_FALSE(InterpolateOdometry(odometry, -1, 1000).has_value());
  EXPECT_FALSE(InterpolateOdometry(odometry, 101, 1000).has_value());
  EXPECT_FALSE(InterpolateOdometry(odometry, 50, 99).has_value());  // samples too far apart
}

// Odometry drifts (x scaled by 0.9, heading 0); the keyframes are corrected poses at t = 0 and
// t = 10 s. A query at 3 s uses keyframe 0 (nearest): X = (0, 0, 0) + odometry motion 0.9 * 3.
// A query at 8 s uses keyframe 10 s, (20, 5, pi/2): odometry motion 8 -> 10 s is -1.8 m in
// x of the odometry frame, so X(8) = (20, 5, pi/2) (+) (-1.8, 0, 0) = (20, 3.2, pi/2).
TEST(CompleteWithOdometryTest, NearestKeyframePlusOdometryMotion) {
  StampedTrajectory odometry;
  for (int i = 0; i <= 20; ++i) odometry.push_back({500000LL * i, Pose2(0.9 * 0.5 * i, 0, 0)});
  const StampedTrajectory keyframes = {{0, Pose2(0, 0, 0)}, {10000000, Pose2(20, 5, M_PI / 2)}};
  const StampedTrajectory completed = CompleteWithOdometry(
      keyframes, odometry, {8000000, 3000000, 3000000, 12000000, 10000000}, 1000000, 1000000);
  ASSERT_EQ(completed.size(), 3u);  // 12 s is beyond the odometry; duplicates merged
  EXPECT_EQ(completed[0].utime, 3000000);
  EXPECT_NEAR(completed[0].pose.x(), 2.7, 1e-12);
  EXPECT_NEAR(completed[0].pose.y(), 0.0, 1e-12);
  EXPECT_EQ(completed[1].utime, 8000000);
  EXPECT_NEAR(completed[1].pose.x(), 20.0, 1e-12);
  EXPECT_NEAR(completed[1].pose.y(), 3.2, 1e-12);
  EXPECT_NEAR(completed[1].pose.theta(), M_PI / 2, 1e-12);
  EXPECT_NEAR(completed[2].pose.y(), 5.0, 1e-12);  // at a keyframe: the keyframe itself
  EXPECT_TRUE(CompleteWithOdometry({}, odometry, {0}, 0, 1000000).empty());
}

}  // namespace
}  // namespace anchormap
