#include "tools/sim/office_plan.h"

#include <gtest/gtest.h>

#include "common/geometry/angle.h"
#include "tools/sim/route_planner.h"
#include "tools/sim/world.h"

namespace anchormap::sim {
namespace {

TEST(OfficePlanTest, OneTileHasExpectedSizeAndPlaces) {
  const FloorPlan plan = BuildOfficePlan(OfficePlanOptions{});
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
  const World world(BuildOfficePlan(OfficePlanOptions{}).walls);
  // From the centre of a corner room, rays towards the outer walls hit them.
  EXPECT_NEAR(world.RayCast({5.0, 3.5}, -kPi / 2, 100.0), 3.5, 1e-9);
  EXPECT_NEAR(world.RayCast({5.0, 3.5}, kPi, 100.0), 5.0, 1e-9);
  // The west room's outer wall has no door on a single tile.
  EXPECT_NEAR(world.RayCast({3.5, 11.0}, kPi, 100.0), 3.5, 1e-9);
}

TEST(OfficePlanTest, NeighbouringTilesConnectThroughDoors) {
  OfficePlanOptions options;
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
  for (int tiles : {1, 2}) {
    OfficePlanOptions options;
    options.tiles_x = tiles;
    options.tiles_y = tiles;
    const FloorPlan plan = BuildOfficePlan(options);
    const RoutePlanner planner(plan, RoutePlannerOptions{});
    for (const Place& place : plan.places) {
      EXPECT_TRUE(planner.IsTraversable(place.position)) << place.position.transpose();
      EXPECT_TRUE(planner.Connected(plan.places.front().position, place.position))
          << tiles << " tiles: " << place.position.transpose();
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
