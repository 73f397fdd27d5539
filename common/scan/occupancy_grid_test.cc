#include "common/scan/occupancy_grid.h"

#include <cmath>
#include <cstdlib>
#include <map>
#include <set>

#include <gtest/gtest.h>

namespace anchormap {
namespace {

TEST(BresenhamTest, LinesAreContiguousAndIncludeBothEnds) {
  for (const auto& [x1, y1] : std::vector<std::pair<int64_t, int64_t>>{
           {10, 3}, {-7, 12}, {0, -5}, {4, 4}, {-9, -2}, {0, 0}}) {
    const auto cells = BresenhamLine(0, 0, x1, y1);
    ASSERT_EQ(cells.size(), static_cast<size_t>(std::max(std::abs(x1), std::abs(y1)) + 1));
    EXPECT_EQ(cells.front(), std::make_pair(int64_t{0}, int64_t{0}));
    EXPECT_EQ(cells.back(), std::make_pair(x1, y1));
    for (size_t i = 1; i < cells.size(); ++i) {
      EXPECT_LE(std::abs(cells[i].first - cells[i - 1].first), 1);
      EXPECT_LE(std::abs(cells[i].second - cells[i - 1].second), 1);
    }
  }
}

// A robot at (1, 1) facing +y sees a wall 2 m ahead with a fan of beams.
TEST(OccupancyGridTest, WallIsOccupiedFreeSpaceIsFreeBehindIsUnknown) {
  OccupancyGridOptions options;
  options.resolution_m = 0.1;
  options.tile_size_cells = 16;
  ASSERT_TRUE(options.Validate().ok());
  OccupancyGrid grid(options);
  LaserScan scan;
  scan.rad0 = -0.3f;
  scan.radstep = 0.01f;
  scan.max_range = 30.0f;
  for (int i = 0; i < 61; ++i) {
    const double angle = scan.rad0 + i * scan.radstep;
    scan.ranges.push_back(
        static_cast<float>(2.05 / std::cos(angle)));  // wall at x = 2.05 (sensor frame)
  }
  const Pose2 T_map_body(1.0, 1.0, kPi / 2);  // sensor x axis = map +y: wall at map y = 3.05
  for (int repeat = 0; repeat < 3; ++repeat) grid.InsertScan(scan, T_map_body);

  const auto wall = grid.CellOf({1.0, 3.05});
  EXPECT_GT(grid.Occupancy(wall.first, wall.second), 80);
  const auto free = grid.CellOf({1.0, 2.0});
  EXPECT_EQ(grid.Occupancy(free.first, free.second), 23);  // 3 misses: p = 0.23
  const auto behind = grid.CellOf({1.0, 4.0});
  EXPECT_EQ(grid.Occupancy(behind.first, behind.second), -1);
  EXPECT_NEAR(*grid.LogOdds(wall.first, wall.second), 3 * options.log_odds_hit, 1e-6);
  EXPECT_NEAR(*grid.LogOdds(free.first, free.second),
              std::max(3 * options.log_odds_miss, options.log_odds_min), 1e-6);
}

TEST(OccupancyGridTest, TilesPlaceCellsWhereTheMessageSaysAndGrowNegative) {
  OccupancyGridOptions options;
  options.resolution_m = 0.5;
  options.tile_size_cells = 8;  // tiles of 4 m
  OccupancyGrid grid(options);
  grid.InsertRay({-5.2, 0.3}, {-5.2, 0.3}, /*hit=*/true);  // one cell, in tile (-2, 0)
  const auto tiles = grid.Tiles(11, 2);
  ASSERT_EQ(tiles.size(), 1u);
  const GridTile& t = tiles[0];
  EXPECT_EQ(t.tile_x, -2);
  EXPECT_EQ(t.tile_y, 0);
  EXPECT_EQ(t.width, 8);
  EXPECT_EQ(t.utime, 11);
  EXPECT_EQ(t.update, 2);
  // The tile's lower-left corner is at (tile_x * width * res, tile_y * height * res) =
  // (-8, 0); the point (-5.2, 0.3) is column 5, row 0 of it.
  int observed = 0;
  for (size_t i = 0; i < t.cells.size(); ++i) {
    if (t.cells[i] == -1) continue;
    ++observed;
    EXPECT_EQ(i, 5u);
    EXPECT_EQ(t.cells[i], 70);  // log-odds 0.85 -> p = 0.70
  }
  EXPECT_EQ(observed, 1);
}

TEST(OccupancyGridTest, LongReturnsAreClippedAndNoReturnsIgnoredByDefault) {
  OccupancyGridOptions options;
  options.resolution_m = 0.1;
  options.max_ray_length_m = 5.0;
  OccupancyGrid grid(options);
  LaserScan scan;
  scan.rad0 = 0.0f;
  scan.radstep = 0.1f;
  scan.max_range = 30.0f;
  scan.ranges = {10.0f, 30.0f};  // beyond the ray limit; a no-return
  grid.InsertScan(scan, Pose2());
  const auto far = grid.CellOf({9.95, 0.05});
  EXPECT_EQ(grid.Occupancy(far.first, far.second), -1);  // clipped: never reached
  const auto end = grid.CellOf({4.95, 0.05});
  EXPECT_LT(grid.Occupancy(end.first, end.second), 50);  // cleared, not hit
  const double c = std::cos(0.1), s = std::sin(0.1);
  const auto along_no_return = grid.CellOf({3.0 * c, 3.0 * s});
  EXPECT_EQ(grid.Occupancy(along_no_return.first, along_no_return.second), -1);
}

// Each cell changes at most once per scan, by a hit if any beam ends there, else by a
// miss: checked against sets built from BresenhamLine, for the stamped window (default
// ray length) and the hash-map path (rays too long for a window at this resolution).
TEST(OccupancyGridTest, EachCellOnceAHitWinsMatchesABruteForceReference) {
  for (double max_ray_m : {4.0, 30.0}) {
    OccupancyGridOptions options;
    options.resolution_m = 0.02;
    options.max_ray_length_m = max_ray_m;  // 4 m: 405-cell window; 30 m: 3005 > 2049
    options.log_odds_min = -100;
    options.log_odds_max = 100;
    ASSERT_TRUE(options.Validate().ok());
    OccupancyGrid grid(options);
    std::map<std::pair<int64_t, int64_t>, double> expected;
    const Pose2 poses[] = {Pose2(0.3, -0.2, 0.4), Pose2(0.5, 0.1, -1.0), Pose2(0.31, -0.19, 0.4)};
    for (const Pose2& T_map_body : poses) {
      LaserScan scan;
      scan.rad0 = -2.0f;
      scan.radstep = 0.013f;
      scan.max_range = 30.0f;
      scan.T_body_sensor = Pose2(0.1, 0.0, 0.05);
      for (int i = 0; i < 300; ++i)
        scan.ranges.push_back(0.5f + 0.01f * static_cast<float>(i % 170));
      grid.InsertScan(scan, T_map_body);
      // Reference: sets of hit and traversed cells of this scan.
      const Pose2 T_map_sensor = Compose(T_map_body, scan.T_body_sensor);
      const auto [x0, y0] = grid.CellOf(T_map_sensor.translation());
      std::set<std::pair<int64_t, int64_t>> hits, misses;
      for (size_t i = 0; i < scan.ranges.size(); ++i) {
        const double a = scan.Angle(i);
        const double length = std::min<double>(scan.ranges[i], max_ray_m);
        const auto end = grid.CellOf(
            T_map_sensor.TransformPoint(length * Eigen::Vector2d(std::cos(a), std::sin(a))));
        const auto line = BresenhamLine(x0, y0, end.first, end.second);
        for (size_t k = 0; k + 1 < line.size(); ++k) misses.insert(line[k]);
        (scan.ranges[i] <= max_ray_m ? hits : misses).insert(end);
      }
      for (const auto& cell : misses) {
        if (!hits.count(cell)) expected[cell] += options.log_odds_miss;
      }
      for (const auto& cell : hits) expected[cell] += options.log_odds_hit;
    }
    ASSERT_GT(expected.size(), 1000u);
    for (const auto& [cell, log_odds] : expected) {
      const std::optional<double> actual = grid.LogOdds(cell.first, cell.second);
      ASSERT_TRUE(actual.has_value()) << cell.first << "," << cell.second;
      EXPECT_NEAR(*actual, log_odds, 1e-5) << cell.first << "," << cell.second;
    }
  }
}

}  // namespace
}  // namespace anchormap
