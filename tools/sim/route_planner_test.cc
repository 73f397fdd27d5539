#include "tools/sim/route_planner.h"

#include <gtest/gtest.h>

#include "tools/sim/office_plan.h"
#include "tools/sim/world.h"

namespace anchormap::sim {
namespace {

// Every point of every leg keeps at least the clearance (exact distance to the walls).
double SmallestDistanceAlongRoute(const World& world, const std::vector<Eigen::Vector2d>& route) {
  double smallest = World::kNoHit;
  for (size_t i = 0; i + 1 < route.size(); ++i) {
    const double length = (route[i + 1] - route[i]).norm();
    const int steps = std::max(1, static_cast<int>(length / 0.02));
    for (int k = 0; k <= steps; ++k) {
      const Eigen::Vector2d p = route[i] + (route[i + 1] - route[i]) * (double(k) / steps);
      smallest = std::min(smallest, world.DistanceToNearestWall(p));
    }
  }
  return smallest;
}

TEST(RoutePlannerTest, RoutesBetweenOfficePlacesKeepTheClearance) {
  const FloorPlan plan = BuildOfficePlan(OfficePlanOptions{});
  const World world(plan.walls);
  const RoutePlannerOptions options;
  const RoutePlanner planner(plan, options);
  int routes = 0;
  for (size_t i = 0; i < plan.places.size(); i += 2) {
    for (size_t j = 1; j < plan.places.size(); j += 3) {
      if (i == j) continue;
      const auto route = planner.Plan(plan.places[i].position, plan.places[j].position);
      ASSERT_GE(route.size(), 2u) << i << " -> " << j;
      EXPECT_EQ(route.front(), plan.places[i].position);
      EXPECT_EQ(route.back(), plan.places[j].position);
      EXPECT_GE(SmallestDistanceAlongRoute(world, route), options.clearance_m) << i << " -> " << j;
      ++routes;
    }
  }
  EXPECT_GT(routes, 100);
}

TEST(RoutePlannerTest, ShortcutsMakeFewLegsInOpenSpace) {
  const FloorPlan plan = BuildOfficePlan(OfficePlanOptions{});
  const RoutePlanner planner(plan, RoutePlannerOptions{});
  // Along the south corridor (y = 8.25) from one end to the other: a straight line is clear,
  // so few legs remain (the centring cost may bend it slightly).
  const auto route = planner.Plan({8.25, 8.25}, {31.75, 8.25});
  ASSERT_GE(route.size(), 2u);
  EXPECT_LE(route.size(), 4u);
}

TEST(RoutePlannerTest, NothingThroughWallsOrOutside) {
  OfficePlanOptions bare;  // the walls where the bare plan has them
  bare.varied_tiles = false;
  const FloorPlan plan = BuildOfficePlan(bare);
  const RoutePlanner planner(plan, RoutePlannerOptions{});
  EXPECT_FALSE(planner.IsTraversable({10.0, 3.5}));   // on a wall between two rooms
  EXPECT_FALSE(planner.IsTraversable({45.0, 15.0}));  // outside the building
  EXPECT_TRUE(planner.Plan({5.0, 3.5}, {45.0, 15.0}).empty());
  EXPECT_FALSE(planner.Connected({5.0, 3.5}, {45.0, 15.0}));
  EXPECT_FALSE(planner.SegmentIsClear({5.0, 3.5}, {13.5, 3.5}));  // through the wall x = 10
  EXPECT_TRUE(planner.SegmentIsClear({8.25, 8.25}, {31.75, 8.25}));
}

TEST(RoutePlannerTest, MaskRestrictsWhereRobotsGo) {
  // A 20 x 10 m box split by a wall at x = 10, with the east half masked as unknown.
  FloorPlan plan;
  plan.walls = {{{0, 0}, {20, 0}}, {{20, 0}, {20, 10}}, {{20, 10}, {0, 10}}, {{0, 10}, {0, 0}}};
  plan.mask.width = 20;
  plan.mask.height = 10;
  plan.mask.resolution_m = 1.0;
  plan.mask.free.assign(200, 0);
  for (int y = 0; y < 10; ++y) {
    for (int x = 0; x < 10; ++x) plan.mask.free[y * 20 + x] = 1;
  }
  const RoutePlanner planner(plan, RoutePlannerOptions{});
  EXPECT_TRUE(planner.IsTraversable({5.0, 5.0}));
  EXPECT_FALSE(planner.IsTraversable({15.0, 5.0}));
  EXPECT_TRUE(planner.Plan({5.0, 5.0}, {15.0, 5.0}).empty());
  EXPECT_GE(planner.Plan({2.0, 2.0}, {8.0, 8.0}).size(), 2u);
  Rng rng(3);
  for (int i = 0; i < 100; ++i) {
    Eigen::Vector2d p;
    ASSERT_TRUE(planner.SampleTraversable(rng, &p));
    EXPECT_LT(p.x(), 10.0);
    EXPECT_TRUE(planner.Connected(p, {5.0, 5.0}));
  }
}

TEST(RoutePlannerTest, PlansAreRepeatable) {
  const FloorPlan plan = BuildOfficePlan(OfficePlanOptions{});
  const RoutePlanner a(plan, RoutePlannerOptions{});
  const RoutePlanner b(plan, RoutePlannerOptions{});
  EXPECT_EQ(a.Plan({5.0, 3.5}, {36.5, 19.0}), b.Plan({5.0, 3.5}, {36.5, 19.0}));
}

TEST(RoutePlannerTest, ValidateChecksClearances) {
  EXPECT_TRUE(RoutePlannerOptions{}.Validate().ok());
  RoutePlannerOptions bad;
  bad.preferred_clearance_m = 0.1;
  EXPECT_FALSE(bad.Validate().ok());
}

}  // namespace
}  // namespace anchormap::sim
