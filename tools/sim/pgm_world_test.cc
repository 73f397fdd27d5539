#include "tools/sim/pgm_world.h"

#include <filesystem>
#include <fstream>

#include <gtest/gtest.h>

#include "common/geometry/angle.h"
#include "tests/testing/scratch.h"
#include "tools/sim/route_planner.h"
#include "tools/sim/world.h"

namespace anchormap::sim {
namespace {

// 20 x 12 pixels at 0.5 m: a 1-pixel black border, a black 2 x 2 block at pixels
// x 9..10, image rows 5..6, and an unknown (grey) strip in image row 1.
GrayImage TestImage() {
  GrayImage image;
  image.width = 20;
  image.height = 12;
  image.pixels.assign(240, 254);
  for (int x = 0; x < 20; ++x) {
    image.pixels[x] = 0;
    image.pixels[11 * 20 + x] = 0;
  }
  for (int y = 0; y < 12; ++y) {
    image.pixels[y * 20] = 0;
    image.pixels[y * 20 + 19] = 0;
  }
  for (int y = 5; y <= 6; ++y) {
    for (int x = 9; x <= 10; ++x) image.pixels[y * 20 + x] = 0;
  }
  for (int x = 1; x < 19; ++x) image.pixels[20 + x] = 205;
  return image;
}

TEST(PgmWorldTest, OccupiedPixelsBecomeWallsAtTheirBorders) {
  MapMetadata metadata;
  metadata.resolution_m = 0.5;
  metadata.origin[0] = 10.0;
  metadata.origin[1] = -2.0;
  const FloorPlan plan = FloorPlanFromImage(TestImage(), metadata);
  const World world(plan.walls);
  // The image spans x in [10, 20], y in [-2, 4]; the border's inner faces are at x = 10.5,
  // 19.5, y = -1.5, 3.5. The block covers pixels x 9..10 -> [14.5, 15.5], image rows 5..6
  // -> grid rows 5..6 -> y in [0.5, 1.5].
  EXPECT_NEAR(world.min_corner().x(), 10.0, 1e-12);
  EXPECT_NEAR(world.max_corner().y(), 4.0, 1e-12);
  const Eigen::Vector2d origin(12.0, 1.0);
  EXPECT_NEAR(world.RayCast(origin, kPi, 100.0), 1.5, 1e-12);       // west inner face
  EXPECT_NEAR(world.RayCast(origin, 0.0, 100.0), 2.5, 1e-12);       // the block's west face
  EXPECT_NEAR(world.RayCast(origin, -kPi / 2, 100.0), 2.5, 1e-12);  // south inner face
  // Unknown pixels are not walls: north goes to the border at 3.5.
  EXPECT_NEAR(world.RayCast(origin, kPi / 2, 100.0), 2.5, 1e-12);
  // Long merged segments, not one per pixel: border (4 outer + 4 inner) + block (4).
  EXPECT_EQ(plan.walls.size(), 12u);
  // The mask: free pixels only; the unknown strip (image row 1 = y in [3, 3.5]) is not.
  EXPECT_TRUE(plan.mask.IsFree({12.0, 1.0}));
  EXPECT_FALSE(plan.mask.IsFree({12.0, 3.2}));
  EXPECT_FALSE(plan.mask.IsFree({15.0, 1.0}));
}

TEST(PgmWorldTest, LoadsPgmAndYamlFiles) {
  const std::filesystem::path dir = ::anchormap::testing::ScratchDir() / "pgm_world_test";
  std::filesystem::create_directories(dir);
  ASSERT_TRUE(WritePgm((dir / "world.pgm").string(), TestImage()).ok());
  {
    std::ofstream yaml(dir / "world.yaml");
    yaml << "image: world.pgm\nresolution: 0.5\norigin: [10.0, -2.0, 0.0]\nnegate: 0\n"
            "occupied_thresh: 0.65\nfree_thresh: 0.196\n";
  }
  FloorPlan from_yaml;
  ASSERT_TRUE(LoadPgmWorld((dir / "world.yaml").string(), 0.05, &from_yaml).ok());
  EXPECT_NEAR(World(from_yaml.walls).RayCast({12.0, 1.0}, kPi, 100.0), 1.5, 1e-12);

  FloorPlan from_pgm;  // the PGM alone: origin (0, 0), resolution from the argument
  ASSERT_TRUE(LoadPgmWorld((dir / "world.pgm").string(), 0.25, &from_pgm).ok());
  EXPECT_NEAR(World(from_pgm.walls).max_corner().x(), 5.0, 1e-12);

  FloorPlan missing;
  const Status status = LoadPgmWorld((dir / "absent.pgm").string(), 0.05, &missing);
  EXPECT_FALSE(status.ok());
  EXPECT_NE(status.message().find("absent.pgm"), std::string::npos);
}

TEST(PgmWorldTest, RobotsCanPlanInAPgmWorld) {
  MapMetadata metadata;
  metadata.resolution_m = 0.5;
  const FloorPlan plan = FloorPlanFromImage(TestImage(), metadata);
  RoutePlannerOptions options;
  options.clearance_m = 0.3;
  options.preferred_clearance_m = 0.5;
  const RoutePlanner planner(plan, options);
  const auto route = planner.Plan({1.5, 1.0}, {8.5, 1.0});  // around the block
  ASSERT_GE(route.size(), 2u);
  const World world(plan.walls);
  for (const auto& p : route) EXPECT_GE(world.DistanceToNearestWall(p), 0.3);
}

}  // namespace
}  // namespace anchormap::sim
