#include "tools/render/occupancy_raster.h"

#include <gtest/gtest.h>

namespace anchormap::render {
namespace {

GridTile Tile(int tile_x, int tile_y, int8_t value, double resolution = 0.5) {
  GridTile tile;
  tile.resolution_m = resolution;
  tile.tile_x = tile_x;
  tile.tile_y = tile_y;
  tile.width = 4;
  tile.height = 3;
  tile.cells.assign(12, value);
  tile.cells[0] = 100;  // bottom-left cell of each tile occupied
  return tile;
}

TEST(OccupancyRasterTest, TilesArePlacedByTheirIndices) {
  int skipped = -1;
  const OccupancyRaster raster = AssembleGrid({Tile(-1, 0, 0), Tile(1, 1, 50)}, &skipped);
  EXPECT_EQ(skipped, 0);
  // Columns -4 .. 7 (tile x -1 .. 1), rows 0 .. 5 (tile y 0 .. 1).
  EXPECT_EQ(raster.width, 12);
  EXPECT_EQ(raster.height, 6);
  EXPECT_DOUBLE_EQ(raster.origin.x(), -2.0);
  EXPECT_DOUBLE_EQ(raster.origin.y(), 0.0);
  EXPECT_DOUBLE_EQ(raster.max_corner().x(), 4.0);
  EXPECT_EQ(raster.at(0, 0), 100);  // tile (-1, 0)'s first cell
  EXPECT_EQ(raster.at(1, 0), 0);
  EXPECT_EQ(raster.at(8, 3), 100);  // tile (1, 1)'s first cell at column 4 - (-4), row 3
  EXPECT_EQ(raster.at(9, 4), 50);
  EXPECT_EQ(raster.at(5, 1), -1);  // tile (0, 0) is absent: unknown
}

TEST(OccupancyRasterTest, MixedResolutionsAreSkipped) {
  int skipped = 0;
  const OccupancyRaster raster = AssembleGrid({Tile(0, 0, 0), Tile(1, 0, 0, 0.25)}, &skipped);
  EXPECT_EQ(skipped, 1);
  EXPECT_EQ(raster.width, 4);
  EXPECT_TRUE(AssembleGrid({}).empty());
}

}  // namespace
}  // namespace anchormap::render
