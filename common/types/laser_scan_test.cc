#include "common/types/laser_scan.h"

#include <cmath>
#include <limits>

#include <gtest/gtest.h>

namespace anchormap {
namespace {

TEST(LaserScanTest, PointsSkipNoReturnsAndApplySensorOffset) {
  LaserScan scan;
  scan.rad0 = 0.0f;
  scan.radstep = static_cast<float>(kPi / 2);
  scan.max_range = 10.0f;
  scan.ranges = {1.0f, 10.0f, std::numeric_limits<float>::quiet_NaN(), 2.0f};
  scan.T_body_sensor = Pose2(0.5, 0.0, 0.0);
  const auto points = scan.PointsInBodyFrame();
  ASSERT_EQ(points.size(), 2u);  // 10 m is max range, NaN is invalid
  EXPECT_NEAR(points[0].x(), 1.5, 1e-6);
  EXPECT_NEAR(points[0].y(), 0.0, 1e-6);
  EXPECT_NEAR(points[1].x(), 0.5, 1e-6);  // ranges[3] at 270 degrees
  EXPECT_NEAR(points[1].y(), -2.0, 1e-6);
}

}  // namespace
}  // namespace anchormap
