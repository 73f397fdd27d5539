#include "tools/render/occupancy_raster.h"

#include <algorithm>
#include <cmath>
#include <limits>

namespace anchormap::render {

OccupancyRaster AssembleGrid(const std::vector<GridTile>& tiles, int* skipped) {
  OccupancyRaster raster;
  int skipped_tiles = 0;
  if (tiles.empty()) {
    if (skipped) *skipped = 0;
    return raster;
  }
  const double resolution = tiles.front().resolution_m;
  auto usable = [&](const GridTile& tile) {
    return std::abs(tile.resolution_m - resolution) <= 1e-9 * resolution;
  };
  int64_t min_x = std::numeric_limits<int64_t>::max();
  int64_t min_y = std::numeric_limits<int64_t>::max();
  int64_t max_x = std::numeric_limits<int64_t>::min();
  int64_t max_y = std::numeric_limits<int64_t>::min();
  for (const GridTile& tile : tiles) {
    if (!usable(tile)) continue;
    const int64_t x0 = static_cast<int64_t>(tile.tile_x) * tile.width;
    const int64_t y0 = static_cast<int64_t>(tile.tile_y) * tile.height;
    min_x = std::min(min_x, x0);
    min_y = std::min(min_y, y0);
    max_x = std::max(max_x, x0 + tile.width);
    max_y = std::max(max_y, y0 + tile.height);
  }
  // A raster beyond 20000 x 20000 cells would be a corrupt tile index, not a map.
  constexpr int64_t kMaxSide = 20000;
  if (max_x - min_x > kMaxSide || max_y - min_y > kMaxSide) {
    if (skipped) *skipped = static_cast<int>(tiles.size());
    return raster;
  }
  raster.resolution_m = resolution;
  raster.origin =
      Eigen::Vector2d(static_cast<double>(min_x), static_cast<double>(min_y)) * resolution;
  raster.width = static_cast<int>(max_x - min_x);
  raster.height = static_cast<int>(max_y - min_y);
  raster.cells.assign(static_cast<size_t>(raster.width) * raster.height, -1);
  for (const GridTile& tile : tiles) {
    if (!usable(tile)) {
      ++skipped_tiles;
      continue;
    }
    const int64_t x0 = static_cast<int64_t>(tile.tile_x) * tile.width - min_x;
    const int64_t y0 = static_cast<int64_t>(tile.tile_y) * tile.height - min_y;
    for (int y = 0; y < tile.height; ++y) {
      std::copy_n(tile.cells.begin() + static_cast<long>(y) * tile.width, tile.width,
                  raster.cells.begin() + static_cast<long>((y0 + y) * raster.width + x0));
    }
  }
  if (skipped) *skipped = skipped_tiles;
  return raster;
}

}  // namespace anchormap::render
