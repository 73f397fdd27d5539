#include "tools/sim/route_follower.h"

#include <gtest/gtest.h>

namespace anchormap::sim {
namespace {

MotionOptions UnitMotion() {
  MotionOptions options;
  options.speed_mps = 1.0;
  options.turn_rate_radps = 1.0;
  return options;
}

TEST(RouteFollowerTest, DrivesStraightThenTurnsInPlace) {
  RouteFollower follower(UnitMotion(), Pose2(0, 0, 0));
  follower.SetRoute({{0, 0}, {2, 0}, {2, 1}});
  EXPECT_EQ(follower.Advance(0.5), 0.0);
  EXPECT_NEAR(follower.pose().x(), 0.5, 1e-12);
  EXPECT_EQ(follower.Advance(1.5), 0.0);
  EXPECT_DOUBLE_EQ(follower.pose().x(), 2.0);  // exactly on the waypoint
  // Turning by 90 degrees takes pi/2 s; halfway through:
  follower.Advance(kPi / 4);
  EXPECT_NEAR(follower.pose().theta(), kPi / 4, 1e-12);
  EXPECT_DOUBLE_EQ(follower.pose().x(), 2.0);
  EXPECT_DOUBLE_EQ(follower.pose().y(), 0.0);
  // The rest of the turn (pi/4 s) and the last metre (1 s), then 0.5 s are left over.
  EXPECT_NEAR(follower.Advance(kPi / 4 + 1.5), 0.5, 1e-12);
  EXPECT_TRUE(follower.Done());
  EXPECT_DOUBLE_EQ(follower.pose().y(), 1.0);
  EXPECT_NEAR(follower.pose().theta(), kPi / 2, 1e-12);
}

TEST(RouteFollowerTest, TurnsTheShortWay) {
  RouteFollower follower(UnitMotion(), Pose2(0, 0, 3.0));
  follower.SetRoute({{0, 0}, {-1, -0.1}});  // heading about -3.04 rad: 0.24 rad away across pi
  follower.Advance(0.1);
  EXPECT_GT(std::abs(follower.pose().theta()), 3.0);  // turned towards +-pi, not through 0
}

TEST(RouteFollowerTest, ValidateRejectsZeroSpeed) {
  EXPECT_TRUE(MotionOptions{}.Validate().ok());
  MotionOptions bad;
  bad.speed_mps = 0.0;
  EXPECT_FALSE(bad.Validate().ok());
}

}  // namespace
}  // namespace anchormap::sim
