#include "tools/sim/simulated_laser.h"

#include <algorithm>
#include <cmath>

#include <gtest/gtest.h>

namespace anchormap::sim {
namespace {

// The room [0, 10] x [0, 6].
World Room() {
  return World({{{0, 0}, {10, 0}}, {{10, 0}, {10, 6}}, {{10, 6}, {0, 6}}, {{0, 6}, {0, 0}}});
}

// Distance from (x, y) inside the room to its walls along world angle `a`, by hand.
double AnalyticRoomDistance(double x, double y, double a) {
  const double c = std::cos(a);
  const double s = std::sin(a);
  double t = 1e300;
  if (c > 1e-15) t = std::min(t, (10.0 - x) / c);
  if (c < -1e-15) t = std::min(t, -x / c);
  if (s > 1e-15) t = std::min(t, (6.0 - y) / s);
  if (s < -1e-15) t = std::min(t, -y / s);
  return t;
}

LaserOptions NoiselessLaser() {
  LaserOptions options;
  options.beams = 361;
  options.fov_deg = 360.0;
  options.max_range_m = 30.0;
  options.range_noise_m = 0.0;
  return options;
}

TEST(SimulatedLaserTest, NoiselessRangesEqualAnalyticDistances) {
  const World world = Room();
  const Pose2 pose(3.0, 2.0, 0.3);
  Rng rng(1);
  const LaserScan scan = SimulatedLaser(NoiselessLaser()).Scan(world, pose, 123, rng);
  ASSERT_EQ(scan.ranges.size(), 361u);
  EXPECT_EQ(scan.utime, 123);
  EXPECT_FLOAT_EQ(scan.rad0, static_cast<float>(-kPi));
  EXPECT_FLOAT_EQ(scan.radstep, static_cast<float>(kPi / 180.0));
  EXPECT_FLOAT_EQ(scan.max_range, 30.0f);
  for (size_t i = 0; i < scan.ranges.size(); ++i) {
    const double expected = AnalyticRoomDistance(3.0, 2.0, 0.3 + scan.Angle(i));
    // Float ranges: relative precision 6e-8.
    ASSERT_NEAR(scan.ranges[i], expected, 1e-6 * expected) << "beam " << i;
    EXPECT_TRUE(scan.IsReturn(i));
  }
  // Beam 180 looks straight ahead (heading 0.3): the right wall at 7 / cos(0.3)
  // (the top wall is at 4 / sin(0.3) = 13.5).
  EXPECT_NEAR(scan.ranges[180], 7.0 / std::cos(0.3), 1e-5);
}

TEST(SimulatedLaserTest, NarrowFieldOfViewIsCentredOnTheHeading) {
  LaserOptions options = NoiselessLaser();
  options.beams = 181;
  options.fov_deg = 180.0;
  const World world = Room();
  Rng rng(1);
  const LaserScan scan = SimulatedLaser(options).Scan(world, Pose2(3.0, 2.0, kPi / 2), 0, rng);
  EXPECT_NEAR(scan.ranges.front(), 7.0, 1e-6);  // -90 deg from north: east wall
  EXPECT_NEAR(scan.ranges[90], 4.0, 1e-6);      // north
  EXPECT_NEAR(scan.ranges.back(), 3.0, 1e-6);   // west
}

TEST(SimulatedLaserTest, BeyondMaxRangeReadsMaxRange) {
  LaserOptions options = NoiselessLaser();
  options.max_range_m = 5.0;
  Rng rng(1);
  const LaserScan scan = SimulatedLaser(options).Scan(Room(), Pose2(3.0, 2.0, 0.0), 0, rng);
  int no_returns = 0;
  for (size_t i = 0; i < scan.ranges.size(); ++i) {
    const double expected = AnalyticRoomDistance(3.0, 2.0, scan.Angle(i));
    if (expected > 5.0) {
      EXPECT_EQ(scan.ranges[i], 5.0f);
      EXPECT_FALSE(scan.IsReturn(i));
      ++no_returns;
    } else if (expected < 4.99) {
      EXPECT_TRUE(scan.IsReturn(i));
    }
  }
  EXPECT_GT(no_returns, 50);
  EXPECT_LT(no_returns, 300);
}

TEST(SimulatedLaserTest, NoiseHasTheConfiguredSpreadAndDropoutGivesNoReturn) {
  LaserOptions options = NoiselessLaser();
  options.range_noise_m = 0.05;
  const World world = Room();
  const Pose2 pose(5.0, 3.0, 0.0);
  Rng rng(9);
  double sum = 0.0;
  double sum_sq = 0.0;
  int n = 0;
  for (int scan_index = 0; scan_index < 50; ++scan_index) {
    const LaserScan scan = SimulatedLaser(options).Scan(world, pose, 0, rng);
    for (size_t i = 0; i < scan.ranges.size(); ++i) {
      const double error = scan.ranges[i] - AnalyticRoomDistance(5.0, 3.0, scan.Angle(i));
      sum += error;
      sum_sq += error * error;
      ++n;
    }
  }
  EXPECT_NEAR(sum / n, 0.0, 0.002);
  EXPECT_NEAR(std::sqrt(sum_sq / n), 0.05, 0.002);

  options.dropout_probability = 1.0;
  const LaserScan dropped = SimulatedLaser(options).Scan(world, pose, 0, rng);
  EXPECT_TRUE(std::all_of(dropped.ranges.begin(), dropped.ranges.end(),
                          [](float r) { return r == 30.0f; }));
}

TEST(SimulatedLaserTest, ValidateRejectsBadOptions) {
  EXPECT_TRUE(LaserOptions{}.Validate().ok());
  LaserOptions bad;
  bad.beams = 1;
  EXPECT_FALSE(bad.Validate().ok());
  bad = LaserOptions{};
  bad.fov_deg = 400.0;
  EXPECT_FALSE(bad.Validate().ok());
  bad = LaserOptions{};
  bad.range_noise_m = -0.1;
  EXPECT_FALSE(bad.Validate().ok());
}

}  // namespace
}  // namespace anchormap::sim
