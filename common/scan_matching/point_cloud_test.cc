#include "common/scan_matching/point_cloud.h"

#include <cmath>
#include <limits>

#include <gtest/gtest.h>

#include "common/geometry/angle.h"

namespace anchormap {
namespace {

TEST(PointCloudTest, AppliesTheMountingPoseAndDropsNoReturns) {
  LaserScan scan;
  scan.rad0 = static_cast<float>(-kPi / 2);
  scan.radstep = static_cast<float>(kPi / 2);
  scan.max_range = 10.0f;
  scan.ranges = {2.0f, 10.0f, std::numeric_limits<float>::quiet_NaN(), 0.0f};
  scan.ranges[1] = 3.0f;                          // straight ahead
  scan.ranges[2] = 10.0f;                         // at max range: no return
  scan.T_body_sensor = Pose2(0.5, 0.1, kPi / 2);  // mounted forward, looking left
  const PointCloud cloud = ScanToPointCloud(scan);
  ASSERT_EQ(cloud.size(), 2u);
  // Beam 0 points to the sensor's right = the body's +x: (0.5 + 2, 0.1).
  EXPECT_NEAR(cloud[0].x(), 2.5, 1e-6);
  EXPECT_NEAR(cloud[0].y(), 0.1, 1e-6);
  // Beam 1 points along the sensor's heading = the body's +y.
  EXPECT_NEAR(cloud[1].x(), 0.5, 1e-6);
  EXPECT_NEAR(cloud[1].y(), 3.1, 1e-6);
}

TEST(PointCloudTest, MaxRangeFilterTransformAndRange) {
  LaserScan scan;
  scan.rad0 = 0.0f;
  scan.radstep = 0.1f;
  scan.max_range = 30.0f;
  scan.ranges = {1.0f, 5.0f, 20.0f};
  EXPECT_EQ(ScanToPointCloud(scan, 10.0).size(), 2u);
  EXPECT_EQ(ScanToPointCloud(scan).size(), 3u);
  EXPECT_EQ(CountScanPoints(scan, 10.0), 2u);
  EXPECT_EQ(CountScanPoints(scan), 3u);
  const PointCloud moved = TransformPointCloud({{1.0, 0.0}}, Pose2(1.0, 2.0, kPi / 2));
  EXPECT_NEAR(moved[0].x(), 1.0, 1e-12);
  EXPECT_NEAR(moved[0].y(), 3.0, 1e-12);
  EXPECT_NEAR(MaxPointRange({{3.0, 4.0}, {1.0, 0.0}}), 5.0, 1e-12);
  EXPECT_EQ(MaxPointRange({}), 0.0);
}

}  // namespace
}  // namespace anchormap
