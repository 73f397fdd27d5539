#include "common/scan_matching/local_map_matcher.h"

#include <cmath>
#include <cstdio>
#include <random>
#include <vector>

#include <gtest/gtest.h>

#include "tests/scan_testing/synthetic_world.h"

namespace anchormap {
namespace {

using testing::HalfCircleLaser;
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
  SyntheticLaser laser = HalfCircleLaser();
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

// A corridor 2.4 m wide and 30 m long, closed at both ends, with pillars and alcoves of
// different sizes at irregular places along its walls (a place is known by what is near it).
SyntheticWorld Corridor() {
  SyntheticWorld world;
  auto wall = [&](double ax, double ay, double bx, double by) {
    world.walls.push_back({Eigen::Vector2d(ax, ay), Eigen::Vector2d(bx, by)});
  };
  wall(0.0, 0.0, 30.0, 0.0);
  wall(0.0, 2.4, 30.0, 2.4);
  wall(0.0, 0.0, 0.0, 2.4);
  wall(30.0, 0.0, 30.0, 2.4);
  const double south[][2] = {{1.7, 0.3},  {4.1, 0.5},  {5.3, 0.2},  {8.9, 0.4},  {12.2, 0.6},
                             {14.0, 0.3}, {17.6, 0.5}, {20.3, 0.2}, {23.8, 0.4}, {26.1, 0.3}};
  for (const auto& [x, w] : south) world.AddBox(x, 0.0, x + w, 0.25);
  const double north[][2] = {{2.8, 0.4},  {6.6, 0.3},  {9.9, 0.6},  {13.1, 0.2}, {15.5, 0.4},
                             {19.0, 0.3}, {21.7, 0.5}, {25.0, 0.2}, {27.4, 0.6}};
  for (const auto& [x, w] : north) world.AddBox(x, 2.15, x + w, 2.4);
  world.min_corner = Eigen::Vector2d(0.0, 0.0);
  world.max_corner = Eigen::Vector2d(30.0, 2.4);
  return world;
}

// In the corridor the scans say the robot stands still (every scan the one taken at the
// start) while odometry drives on 0.1 m per scan, as ACES's corridors held the match back
// (4.7 m of odometry in 8 s matched as 0.7 m). Unchecked, the map holds the robot where it
// started; the held-back rule refuses the match once odometry has driven
// held_back_min_odometry_m past the map's newest scan, and restarts the map there.
TEST(LocalMapMatcherTest, AMatchHoldingTheRobotBackInACorridorIsRefused) {
  const SyntheticWorld world = Corridor();
  std::mt19937_64 rng(11);
  const PointCloud points =
      ScanToPointCloud(SimulateScan(world, HalfCircleLaser(), Pose2(3.0, 1.2, 0.0), &rng));
  for (const bool rule : {true, false}) {
    LocalMapMatcherOptions options;
    if (!rule) options.held_back_min_odometry_m = 1e9;
    LocalMapMatcher matcher(options);
    Pose2 odometry;
    double worst_lag = 0.0;
    for (int i = 0; i < 50; ++i) {
      odometry = Compose(odometry, Pose2(i == 0 ? 0.0 : 0.1, 0.0, 0.0));
      const LocalMapUpdate update = matcher.AddScan(points, odometry);
      worst_lag = std::max(worst_lag, (update.pose.translation() - odometry.translation()).norm());
    }
    const LocalMapStats& stats = matcher.stats();
    std::printf("rule %d: worst lag behind odometry %.3f m, held back %lld, matched %lld of %lld\n",
                rule ? 1 : 0, worst_lag, static_cast<long long>(stats.held_back),
                static_cast<long long>(stats.matched), static_cast<long long>(stats.scans));
    if (rule) {
      // Less than held_back_min_odometry_m plus one scan's drive, then a restart.
      EXPECT_LT(worst_lag, 1.15);
      EXPECT_GE(stats.held_back, 4);
      EXPECT_EQ(stats.resets, stats.held_back);
    } else {
      EXPECT_GT(worst_lag, 4.5);  // the map held the robot where it started
      EXPECT_EQ(stats.held_back, 0);
    }
  }
}

// Driving down the same corridor with odometry 10 % long and one slip of 0.3 m (one keyframe
// spacing of the map) at 2 m: the match snaps the pose back onto the map, and the rule lets
// it (the snap corrects the slip once; the next keyframe follows the matched pose).
TEST(LocalMapMatcherTest, ATrueSnapOfOneMapSpacingIsAccepted) {
  const SyntheticWorld world = Corridor();
  std::mt19937_64 rng(12);
  LocalMapMatcher matcher(LocalMapMatcherOptions{});
  Pose2 truth(1.0, 1.2, 0.0);
  Pose2 odometry;
  double worst_error = 0.0, slip_correction = 0.0, error_after_slip = 0.0;
  for (int i = 0; i < 120; ++i) {
    if (i > 0) {
      truth = Compose(truth, Pose2(0.1, 0.0, 0.0));
      odometry = Compose(odometry, Pose2(i == 20 ? 0.41 : 0.11, 0.0, 0.0));
    }
    const PointCloud points = ScanToPointCloud(SimulateScan(world, HalfCircleLaser(), truth, &rng));
    const LocalMapUpdate update = matcher.AddScan(points, odometry);
    // The local frame is the odometry frame of the first scan, which stood at (1.0, 1.2).
    const double error =
        (update.pose.translation() + Eigen::Vector2d(1.0, 1.2) - truth.translation()).norm();
    worst_error = std::max(worst_error, error);
    if (i == 20) {
      slip_correction = (update.predicted.translation() - update.pose.translation()).norm();
      error_after_slip = error;
    }
  }
  const LocalMapStats& stats = matcher.stats();
  std::printf(
      "worst error %.3f m, slip corrected by %.3f m (error then %.3f m), held back %lld, "
      "matched %lld of %lld\n",
      worst_error, slip_correction, error_after_slip, static_cast<long long>(stats.held_back),
      static_cast<long long>(stats.matched), static_cast<long long>(stats.scans));
  EXPECT_EQ(stats.held_back, 0);
  EXPECT_GE(stats.matched, 115);
  EXPECT_NEAR(slip_correction, 0.3, 0.05);
  EXPECT_LT(error_after_slip, 0.05);
  // Scan-to-map drift over the 12 m, about 1 % (odometry ends 1.5 m off).
  EXPECT_LT(worst_error, 0.15);
}

// A plain corridor 2.4 m wide and 200 m long: shifted along its axis a scan fits as well as
// anywhere, so only odometry knows the position along it. Unchecked, the match holds the robot
// at the map's first scan (its far returns, too far apart on the grazing walls to be joined,
// repeat that scan's beam pattern best where it was taken; ACES: 4.7 m of odometry in 8 s
// matched as 0.7 m) until the held-back rule restarts the map, and on ACES's real corridors the
// optimum slides to the window's edge, flipping sign from scan to scan. Odometry here is 5 %
// long and drifts sideways by 5 mm per 0.1 m step. The laser sees all round (looking ahead
// only, the first scans' score keeps 0.946 of itself shifted: flat at 0.9, not at 0.95).
TEST(LocalMapMatcherTest, InAFeaturelessCorridorThePoseFollowsOdometryAlongTheAxis) {
  SyntheticWorld corridor;
  corridor.walls = {{{-100.0, 0.0}, {100.0, 0.0}}, {{-100.0, 2.4}, {100.0, 2.4}}};
  corridor.min_corner = {-100.0, 0.0};
  corridor.max_corner = {100.0, 2.4};
  SyntheticLaser laser;  // all round, 1-degree beams
  laser.beams = 360;
  laser.fov_rad = 2.0 * 3.14159265358979323846;
  laser.max_range_m = 30.0;  // the matcher cuts at 15 m
  laser.range_sigma_m = 0.01;
  for (const bool rule : {true, false}) {
    LocalMapMatcherOptions options;
    options.follow_odometry_along_flat_direction = rule;
    LocalMapMatcher matcher(options);
    std::mt19937_64 rng(21);
    Pose2 truth(0.0, 1.2, 0.0);
    Pose2 odometry;
    double worst_along = 0.0;   // |matched - odometry| along the axis
    double worst_across = 0.0;  // |matched - truth| across it
    double min_sd_along = 1e9, max_sd_across = 0.0;
    for (int i = 0; i < 40; ++i) {
      if (i > 0) {
        truth = Compose(truth, Pose2(0.1, 0.0, 0.0));
        odometry = Compose(odometry, Pose2(0.105, 0.005, 0.0));
      }
      const PointCloud points = ScanToPointCloud(SimulateScan(corridor, laser, truth, &rng));
      const LocalMapUpdate update =
          matcher.AddScan(points, odometry, [](const Pose2&) { return true; });
      if (!update.matched) continue;
      // The local frame is the first scan's odometry frame, which stood at (0, 1.2).
      worst_along = std::max(worst_along, std::abs(update.pose.x() - odometry.x()));
      worst_across = std::max(worst_across, std::abs(update.pose.y() + 1.2 - truth.y()));
      min_sd_along = std::min(min_sd_along, std::sqrt(update.match->covariance(0, 0)));
      max_sd_across = std::max(max_sd_across, std::sqrt(update.match->covariance(1, 1)));
    }
    const LocalMapStats& stats = matcher.stats();
    std::printf(
        "rule %d: worst along-axis departure from odometry %.3f m, worst across error %.3f m, "
        "sd along >= %.3f m, across <= %.4f m, flat %lld, matched %lld of %lld\n",
        rule ? 1 : 0, worst_along, worst_across, min_sd_along, max_sd_across,
        static_cast<long long>(stats.flat), static_cast<long long>(stats.matched),
        static_cast<long long>(stats.scans));
    if (rule) {
      EXPECT_EQ(stats.matched, 39);  // every scan after the first
      EXPECT_EQ(stats.flat, stats.matched);
      EXPECT_EQ(stats.held_back, 0);
      EXPECT_LT(worst_along, 0.01);
      // Across the corridor the match corrects odometry's 0.2 m of drift.
      EXPECT_LT(worst_across, 0.01);
      // The window's reach (0.4 m) along the axis, not the refinement's millimetres.
      EXPECT_GE(min_sd_along, 0.4);
      EXPECT_LT(max_sd_across, 0.01);
    } else {
      EXPECT_EQ(stats.flat, 0);
      EXPECT_GT(worst_along, 0.5);  // held back, then restarted where odometry had drifted
      EXPECT_GE(stats.held_back, 2);
      EXPECT_LT(min_sd_along, 0.01);  // while claiming millimetres along the axis
    }
  }
}

// The flat test's reach is the window's half-width (the covariance gets it along the axis):
// options that change one without the other are refused.
TEST(LocalMapMatcherTest, TheFlatReachMustBeTheWindowsHalfWidth) {
  LocalMapMatcherOptions options;
  EXPECT_TRUE(options.Validate().ok());
  options.match.linear_window_m = 0.6;
  EXPECT_FALSE(options.Validate().ok());
  options.flat_direction.reach_m = 0.6;
  EXPECT_TRUE(options.Validate().ok());
}

}  // namespace
}  // namespace anchormap
