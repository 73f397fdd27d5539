#include "tools/sim/office_plan.h"

#include <algorithm>
#include <cmath>

#include <gtest/gtest.h>

#include "common/geometry/angle.h"
#include "tools/sim/route_planner.h"
#include "tools/sim/world.h"

namespace anchormap::sim {
namespace {

OfficePlanOptions Bare() {
  OfficePlanOptions options;
  options.varied_tiles = false;
  return options;
}

// Beams (1 degree apart) whose ranges from `a` (heading 0) and from `b` (heading
// `b_heading`) differ by more than 0.3 m: how unlike the two places look to a laser.
int DifferingBeams(const World& world, const Eigen::Vector2d& a, const Eigen::Vector2d& b,
                   double b_heading) {
  int differing = 0;
  for (int i = 0; i < 360; ++i) {
    const double angle = i * kPi / 180.0;
    const double ra = std::min(world.RayCast(a, angle, 30.0), 30.0);
    const double rb = std::min(world.RayCast(b, angle + b_heading, 30.0), 30.0);
    if (std::abs(ra - rb) > 0.3) ++differing;
  }
  return differing;
}

TEST(OfficePlanTest, OneTileHasExpectedSizeAndPlaces) {
  const FloorPlan plan = BuildOfficePlan(Bare());
  const World world(plan.walls);
  EXPECT_DOUBLE_EQ(world.min_corner().x(), 0.0);
  EXPECT_DOUBLE_EQ(world.min_corner().y(), 0.0);
  EXPECT_DOUBLE_EQ(world.max_corner().x(), 40.0);
  EXPECT_DOUBLE_EQ(world.max_corner().y(), 30.0);
  int rooms = 0;
  int corridors = 0;
  for (const Place& place : plan.places) (place.is_room ? rooms : corridors)++;
  EXPECT_EQ(rooms, 18);
  EXPECT_EQ(corridors, 9);
  // Every place is at least a metre from any wall.
  for (const Place& place : plan.places) {
    EXPECT_GE(world.DistanceToNearestWall(place.position), 1.0) << place.position.transpose();
  }
}

TEST(OfficePlanTest, OuterWallIsClosedForOneTile) {
  const World world(BuildOfficePlan(Bare()).walls);
  // From the centre of a corner room, rays towards the outer walls hit them.
  EXPECT_NEAR(world.RayCast({5.0, 3.5}, -kPi / 2, 100.0), 3.5, 1e-9);
  EXPECT_NEAR(world.RayCast({5.0, 3.5}, kPi, 100.0), 5.0, 1e-9);
  // The west room's outer wall has no door on a single tile.
  EXPECT_NEAR(world.RayCast({3.5, 11.0}, kPi, 100.0), 3.5, 1e-9);
}

TEST(OfficePlanTest, NeighbouringTilesConnectThroughDoors) {
  OfficePlanOptions options = Bare();
  options.tiles_x = 2;
  options.tiles_y = 2;
  const World world(BuildOfficePlan(options).walls);
  // Through the door in the shared west wall of tile (1, 0) at y = 11.
  EXPECT_TRUE(world.LineOfSight({36.5, 11.0}, {43.5, 11.0}));
  // Through the door in the shared south wall of tile (0, 1) at x = 20.
  EXPECT_TRUE(world.LineOfSight({20.0, 26.5}, {20.0, 33.5}));
  EXPECT_FALSE(world.LineOfSight({36.5, 19.0}, {43.5, 19.0}));
}

TEST(OfficePlanTest, EveryPlaceIsReachableFromEveryOther) {
  for (uint64_t seed : {1, 2, 3, 4, 5}) {
    for (int tiles : {1, 2}) {
      OfficePlanOptions options;
      options.seed = seed;
      options.tiles_x = tiles;
      options.tiles_y = tiles;
      options.varied_tiles = seed != 5;  // seed 5 stands for the bare plan
      const FloorPlan plan = BuildOfficePlan(options);
      const World world(plan.walls);
      const RoutePlanner planner(plan, RoutePlannerOptions{});
      for (const Place& place : plan.places) {
        EXPECT_GE(world.DistanceToNearestWall(place.position), 1.0)
            << "seed " << seed << ": " << place.position.transpose();
        EXPECT_TRUE(planner.IsTraversable(place.position)) << place.position.transpose();
        EXPECT_TRUE(planner.Connected(plan.places.front().position, place.position))
            << "seed " << seed << ", " << tiles << " tiles: " << place.position.transpose();
      }
    }
  }
}

TEST(OfficePlanTest, TheSameSeedBuildsTheSamePlan) {
  OfficePlanOptions options;
  options.tiles_x = 2;
  options.seed = 7;
  const FloorPlan a = BuildOfficePlan(options);
  const FloorPlan b = BuildOfficePlan(options);
  ASSERT_EQ(a.walls.size(), b.walls.size());
  for (size_t i = 0; i < a.walls.size(); ++i) {
    EXPECT_EQ(a.walls[i].a, b.walls[i].a);
    EXPECT_EQ(a.walls[i].b, b.walls[i].b);
  }
  options.seed = 8;
  const FloorPlan c = BuildOfficePlan(options);
  bool differs = c.walls.size() != a.walls.size();
  for (size_t i = 0; !differs && i < a.walls.size(); ++i) differs = a.walls[i].a != c.walls[i].a;
  EXPECT_TRUE(differs);
}

// The bare tile is point-symmetric about its centre and repeats exactly: a place, its
// copy in the next tile and its half-turn look the same to a laser. Varied tiles do not.
TEST(OfficePlanTest, NoPlaceLooksLikeItsCopyInAnotherTileOrItsHalfTurn) {
  const Eigen::Vector2d shift(kOfficeTileWidthM, 0.0);
  const Eigen::Vector2d centre(20.0, 15.0);
  for (bool varied : {false, true}) {
    for (uint64_t seed : {1, 3, 4}) {
      OfficePlanOptions options;
      options.tiles_x = 3;
      options.seed = seed;
      options.varied_tiles = varied;
      const FloorPlan plan = BuildOfficePlan(options);
      const World world(plan.walls);
      // Places of the middle tile, whose neighbours on both sides are drawn.
      int fewest_shifted = 360;
      int fewest_turned = 360;
      for (const Place& place : plan.places) {
        if (place.region != 1) continue;
        const Eigen::Vector2d p = place.position;
        fewest_shifted = std::min(fewest_shifted, DifferingBeams(world, p, p + shift, 0.0));
        const Eigen::Vector2d turned = 2.0 * (centre + shift) - p;
        fewest_turned = std::min(fewest_turned, DifferingBeams(world, p, turned, kPi));
      }
      if (varied) {
        EXPECT_GE(fewest_shifted, 5) << "seed " << seed;
        EXPECT_GE(fewest_turned, 5) << "seed " << seed;
      } else {
        EXPECT_LE(fewest_shifted, 1) << "seed " << seed;
        EXPECT_LE(fewest_turned, 1) << "seed " << seed;
      }
    }
  }
}

TEST(OfficePlanTest, TilesForRobots) {
  EXPECT_EQ(OfficeTilesForRobots(3, 6).tiles_x, 1);
  EXPECT_EQ(OfficeTilesForRobots(3, 6).tiles_y, 1);
  const OfficePlanOptions hundred = OfficeTilesForRobots(100, 6);  // 17 tiles -> 5 x 4
  EXPECT_EQ(hundred.tiles_x, 5);
  EXPECT_EQ(hundred.tiles_y, 4);
  EXPECT_TRUE(hundred.Validate().ok());
  OfficePlanOptions bad;
  bad.tiles_x = 0;
  EXPECT_FALSE(bad.Validate().ok());
}

}  // namespace
}  // namespace anchormap::sim
