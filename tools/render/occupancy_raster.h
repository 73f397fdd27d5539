#pragma once
// The occupancy grid as one raster, assembled from the server's tiles: what the PNG's
// background and the PGM file are made of.

#include <cstdint>
#include <vector>

#include <Eigen/Core>

#include "tools/render/server_output.h"

namespace anchormap::render {

struct OccupancyRaster {
  double resolution_m = 0.05;
  Eigen::Vector2d origin{0.0, 0.0};  // world position of the lower-left corner of cell (0, 0)
  int width = 0;
  int height = 0;
  std::vector<int8_t> cells;  // row-major, row 0 at the bottom; 0..100, -1 unknown

  bool empty() const { return cells.empty(); }
  int8_t at(int x, int y) const { return cells[static_cast<size_t>(y) * width + x]; }
  Eigen::Vector2d max_corner() const {
    return origin + Eigen::Vector2d(width, height) * resolution_m;
  }
};

// Places every tile at (tile_x * width, tile_y * height) cells; cells no tile covers are
// unknown. Tiles whose resolution differs from the first tile's are skipped and counted in
// `skipped` (when given). Returns an empty raster when there are no tiles.
OccupancyRaster AssembleGrid(const std::vector<GridTile>& tiles, int* skipped = nullptr);

}  // namespace anchormap::render
