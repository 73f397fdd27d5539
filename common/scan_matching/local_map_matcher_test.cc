#include "common/scan_matching/local_map_matcher.h"

#include <cmath>
#include <cstdio>
#include <random>
#include <vector>

#include <gtest/gtest.h>

#include "tests/scan_testing/synthetic_world.h"

namespace anchormap {
namespace {

using testing::RandomFreePose;
using testing::RandomRoom;
using testing::SimulateScan;
using testing::SyntheticLaser;
using testing::SyntheticWorld;

// A wandering path in free space: 0.1 m steps, turning away from walls.
std::vector<Pose2> WanderingPath(const SyntheticWorld& world, int steps, std::mt19937_64* rng) {
  std::uniform_real_distribution<double> turn(-0.08, 0.08);
  std::vector<Pose2> path{RandomFreePose(world, 1.0, rng)};
  while (static_cast<int>(path.size()) < steps) {
    Pose2 next = Compose(path.back(), Pose2(0.1, 0.0, turn(*rng)));
    if (world.DistanceToNearestWall(Compose(next, Pose2(0.6, 0.0, 0.0)).translation()) < 0.4 ||
        world.DistanceToNearestWall(next.translation()) < 0.5) {
      next = Compose(path.back(), Pose2(0.0, 0.0, 0.3));  // turn on the spot
    }
    path.push_back(next);
  }
  return path;
}

TEST(LocalMapMatcherTest, RefinesDriftingOdometry) {
  // Two rooms, 150 steps each (15 m of travel), odometry with 3 % scale error, 1 degree per
  // metre of heading bias and random noise. The refined trajectory's error against the truth
  // (end pose relative to the start) must be a small fraction of odometry's.
  SyntheticLaser laser;
  laser.beams = 181;
  laser.fov_rad = 3.14159265358979323846;
  laser.range_sigma_m = 0.01;
  for (uint64_t seed = 0; seed < 2; ++seed) {
    std::mt19937_64 rng(700 + seed);
    const SyntheticWorld world = RandomRoom(700 + seed);
    const std::vector<Pose2> truth = WanderingPath(world, 150, &rng);
    std::normal_distribution<double> noise(0.0, 1.0);
    LocalMapMatcher matcher(LocalMapMatcherOptions{});
    Pose2 odometry = truth[0];
    double worst_refined = 0.0;
    double worst_odometry = 0.0;
    for (size_t i = 0; i < truth.size(); ++i) {
      if (i > 0) {
        const Pose2 d = Between(truth[i - 1], truth[i]);
        const double dist = d.translation().norm();
        // One draw per statement: a call's argument order is unspecified (gcc's order kept).
        const double noise_theta = 0.005 * noise(rng);
        const double noise_x = 0.005 * noise(rng);
        odometry = Compose(odometry, Pose2(1.03 * d.x() + noise_x, d.y(),
                                           d.theta() + 0.0175 * dist + noise_theta));
      }
      const PointCloud points = ScanToPointCloud(SimulateScan(world, laser, truth[i], &rng));
      const LocalMapUpdate update = matcher.AddScan(points, odometry);
      const Pose2 truth_rel = Between(truth[0], truth[i]);
      const double refined_error =
          PoseError(truth_rel, Between(truth[0], update.pose)).head<2>().norm();
      const double odometry_error =
          PoseError(truth_rel, Between(truth[0], odometry)).head<2>().norm();
      worst_refined = std::max(worst_refined, refined_error);
      worst_odometry = std::max(worst_odometry, odometry_error);
    }
    const LocalMapStats& stats = matcher.stats();
    std::printf(
        "room %d: worst error odometry %.3f m, refined %.3f m; matched %lld of %lld, "
        "keyframes %lld, resets %lld\n",
        static_cast<int>(seed), worst_odometry, worst_refined,
        static_cast<long long>(stats.matched), static_cast<long long>(stats.scans),
        static_cast<long long>(stats.keyframes), static_cast<long long>(stats.resets));
    EXPECT_GT(worst_odometry, 0.5);
    EXPECT_LT(worst_refined, 0.15);
    EXPECT_GE(stats.matched, 146);
    EXPECT_LE(matcher.num_keyframes(), 10u);
  }
}

TEST(LocalMapMatcherTest, FirstScanAnchorsAndEmptyScansFallBackToOdometry) {
  LocalMapMatcher matcher(LocalMapMatcherOptions{});
  const LocalMapUpdate first = matcher.AddScan({}, Pose2(1.0, 2.0, 0.5));
  EXPECT_FALSE(first.matched);
  EXPECT_FALSE(first.keyframe);
  EXPECT_NEAR(PoseError(first.pose, Pose2(1.0, 2.0, 0.5)).norm(), 0.0, 1e-12);
  const LocalMapUpdate second = matcher.AddScan({{1.0, 0.0}, {1.0, 0.05}}, Pose2(1.5, 2.0, 0.5));
  EXPECT_TRUE(second.keyframe);
  EXPECT_FALSE(second.matched);
  const LocalMapUpdate third = matcher.AddScan({}, Pose2(1.6, 2.0, 0.5));
  EXPECT_FALSE(third.matched);
  EXPECT_NEAR(PoseError(third.pose, Pose2(1.6, 2.0, 0.5)).norm(), 0.0, 1e-9);
  EXPECT_EQ(matcher.stats().no_match, 1);
}

}  // namespace
}  // namespace anchormap
