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

TEST(PointCloudTest, PointsAreTheMountingPoseOfEachBeamToTheBitAcrossScanGeometries) {
  // Each point is T_body_sensor.TransformPoint((r cos a, r sin a)) of its beam, bit for bit,
  // whatever scans were converted before: the beams' directions are kept per scan geometry,
  // so scans of two geometries in turn, a longer scan after a shorter one and a shorter one
  // after a longer one must each come out as if converted alone.
  auto make = [](float rad0, float radstep, size_t n, const Pose2& mount) {
    LaserScan scan;
    scan.rad0 = rad0;
    scan.radstep = radstep;
    scan.max_range = 30.0f;
    scan.T_body_sensor = mount;
    for (size_t i = 0; i < n; ++i) scan.ranges.push_back(1.0f + 0.37f * static_cast<float>(i % 40));
    return scan;
  };
  const LaserScan a = make(-2.0f, 0.0175f, 181, Pose2(0.2, -0.05, 0.01));
  const LaserScan b = make(-1.5f, 0.0061f, 361, Pose2(-0.1, 0.3, -0.4));
  const LaserScan a_short = make(-2.0f, 0.0175f, 90, Pose2(0.0, 0.0, 1.0));
  const LaserScan a_long = make(-2.0f, 0.0175f, 400, Pose2(1.0, 2.0, 3.0));
  int checked = 0;
  for (const LaserScan* scan : {&a, &b, &a, &a_short, &a_long, &a_short, &b}) {
    const PointCloud cloud = ScanToPointCloud(*scan, 12.0);
    size_t k = 0;
    for (size_t i = 0; i < scan->ranges.size(); ++i) {
      const double r = scan->ranges[i];
      if (r > 12.0) continue;
      const double angle = scan->Angle(i);
      const Eigen::Vector2d expected =
          scan->T_body_sensor.TransformPoint({r * std::cos(angle), r * std::sin(angle)});
      ASSERT_LT(k, cloud.size());
      EXPECT_EQ(cloud[k].x(), expected.x()) << i;
      EXPECT_EQ(cloud[k].y(), expected.y()) << i;
      ++k;
      ++checked;
    }
    EXPECT_EQ(k, cloud.size());
  }
  EXPECT_GT(checked, 1000);
}

}  // namespace
}  // namespace anchormap
