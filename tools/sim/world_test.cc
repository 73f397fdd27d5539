#include "tools/sim/world.h"

#include <cmath>

#include <gtest/gtest.h>

#include "common/geometry/angle.h"
#include "tools/sim/office_plan.h"
#include "tools/sim/random.h"

namespace anchormap::sim {
namespace {

// The room [0, 10] x [0, 6].
std::vector<WallSegment> Room() {
  return {{{0, 0}, {10, 0}}, {{10, 0}, {10, 6}}, {{10, 6}, {0, 6}}, {{0, 6}, {0, 0}}};
}

// Brute force: the nearest hit over every wall, for checking the bucket traversal.
double BruteForceRayCast(const World& world, const Eigen::Vector2d& origin, double angle,
                         double max_range) {
  const Eigen::Vector2d d(std::cos(angle), std::sin(angle));
  double best = World::kNoHit;
  for (const WallSegment& wall : world.walls()) {
    const Eigen::Vector2d e = wall.b - wall.a;
    const double denominator = d.x() * e.y() - d.y() * e.x();
    if (std::abs(denominator) < 1e-12) continue;
    const Eigen::Vector2d w = wall.a - origin;
    const double t = (w.x() * e.y() - w.y() * e.x()) / denominator;
    const double u = (w.x() * d.y() - w.y() * d.x()) / denominator;
    if (t >= 0.0 && u >= -1e-9 && u <= 1.0 + 1e-9) best = std::min(best, t);
  }
  return best <= max_range ? best : World::kNoHit;
}

TEST(WorldTest, RayCastInRectangularRoomIsExact) {
  const World world(Room());
  const Eigen::Vector2d origin(3.0, 2.0);
  EXPECT_NEAR(world.RayCast(origin, 0.0, 100.0), 7.0, 1e-12);
  EXPECT_NEAR(world.RayCast(origin, kPi / 2, 100.0), 4.0, 1e-12);
  EXPECT_NEAR(world.RayCast(origin, kPi, 100.0), 3.0, 1e-12);
  EXPECT_NEAR(world.RayCast(origin, -kPi / 2, 100.0), 2.0, 1e-12);
  // Into the corner (10, 6): the ray ends exactly where two walls meet.
  EXPECT_NEAR(world.RayCast(origin, std::atan2(4.0, 7.0), 100.0), std::sqrt(65.0), 1e-12);
  // 30 degrees: the top wall at t = 4 / sin(30) = 8 comes before the right wall (8.08).
  EXPECT_NEAR(world.RayCast(origin, kPi / 6, 100.0), 8.0, 1e-12);
  // -135 degrees from (3, 2): the bottom wall at (1, 0), t = 2 * sqrt(2).
  EXPECT_NEAR(world.RayCast(origin, -3 * kPi / 4, 100.0), 2.0 * std::sqrt(2.0), 1e-12);
}

TEST(WorldTest, MaxRangeCutsOff) {
  const World world(Room());
  EXPECT_EQ(world.RayCast({3.0, 2.0}, 0.0, 6.999), World::kNoHit);
  EXPECT_NEAR(world.RayCast({3.0, 2.0}, 0.0, 7.0), 7.0, 1e-12);
}

TEST(WorldTest, OriginOutsideWallsAndEmptyWorld) {
  const World world(Room());
  EXPECT_NEAR(world.RayCast({-5.0, 3.0}, 0.0, 100.0), 5.0, 1e-12);  // hits the west wall
  EXPECT_EQ(world.RayCast({-5.0, 3.0}, kPi, 100.0), World::kNoHit);
  const World empty({});
  EXPECT_EQ(empty.RayCast({0.0, 0.0}, 0.0, 100.0), World::kNoHit);
}

TEST(WorldTest, LineOfSightStopsAtWalls) {
  std::vector<WallSegment> walls = Room();
  walls.push_back({{5, 0}, {5, 4}});  // a partition with a gap above y = 4
  const World world(walls);
  EXPECT_FALSE(world.LineOfSight({2, 2}, {8, 2}));
  EXPECT_TRUE(world.LineOfSight({2, 5}, {8, 5}));
  EXPECT_TRUE(world.LineOfSight({2, 2}, {4, 3}));
  EXPECT_TRUE(world.LineOfSight({2, 2}, {2, 2}));
}

TEST(WorldTest, BucketTraversalEqualsBruteForceInTheOffice) {
  OfficePlanOptions options;
  options.tiles_x = 2;
  const World world(BuildOfficePlan(options).walls, 1.0);
  Rng rng(17);
  int hits = 0;
  for (int i = 0; i < 20000; ++i) {
    // One draw per statement: a call's argument order is unspecified (gcc's order kept).
    const double origin_y = rng.Uniform(-5.0, 35.0);
    const double origin_x = rng.Uniform(-5.0, 85.0);
    const Eigen::Vector2d origin(origin_x, origin_y);
    const double angle = rng.Uniform(-kPi, kPi);
    const double max_range = rng.Uniform(0.5, 60.0);
    const double fast = world.RayCast(origin, angle, max_range);
    const double slow = BruteForceRayCast(world, origin, angle, max_range);
    if (slow == World::kNoHit) {
      ASSERT_EQ(fast, World::kNoHit) << origin.transpose() << " " << angle;
    } else {
      ASSERT_NEAR(fast, slow, 1e-9) << origin.transpose() << " " << angle;
      ++hits;
    }
  }
  EXPECT_GT(hits, 15000);
}

TEST(WorldTest, DistanceToNearestWall) {
  const World world(Room());
  EXPECT_DOUBLE_EQ(world.DistanceToNearestWall({3.0, 2.0}), 2.0);
  EXPECT_DOUBLE_EQ(world.DistanceToNearestWall({13.0, 10.0}), 5.0);  // to the corner (10, 6)
  EXPECT_DOUBLE_EQ(PointSegmentDistance({0, 1}, {-1, 0}, {1, 0}), 1.0);
}

}  // namespace
}  // namespace anchormap::sim
