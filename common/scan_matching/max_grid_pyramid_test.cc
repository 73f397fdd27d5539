#include "common/scan_matching/max_grid_pyramid.h"

#include <algorithm>
#include <random>

#include <gtest/gtest.h>

namespace anchormap {
namespace {

LikelihoodGrid RandomGrid(int width, int height, uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<float> unit(0.0f, 1.0f);
  GridGeometry g;
  g.width = width;
  g.height = height;
  std::vector<float> values(g.num_cells());
  for (float& v : values) v = unit(rng) < 0.3f ? unit(rng) : 0.0f;
  return LikelihoodGrid(g, values);
}

TEST(MaxGridPyramidTest, EveryLevelEqualsBruteForceBlockMaxima) {
  for (uint64_t seed = 1; seed <= 5; ++seed) {
    const LikelihoodGrid grid =
        RandomGrid(13 + static_cast<int>(seed), 9 + 2 * static_cast<int>(seed), seed);
    const MaxGridPyramid pyramid(grid, 5);
    const GridGeometry& g = grid.geometry();
    for (int level = 0; level < pyramid.num_levels(); ++level) {
      const int w = 1 << level;
      // Including blocks that only reach into the grid and blocks entirely outside it.
      for (int iy = -w - 2; iy < g.height + 2; ++iy) {
        for (int ix = -w - 2; ix < g.width + 2; ++ix) {
          float expected = 0.0f;
          for (int y = iy; y < iy + w; ++y) {
            for (int x = ix; x < ix + w; ++x) expected = std::max(expected, grid.Value(x, y));
          }
          ASSERT_EQ(pyramid.Value(level, ix, iy), expected)
              << "seed " << seed << " level " << level << " cell " << ix << " " << iy;
        }
      }
    }
  }
}

}  // namespace
}  // namespace anchormap
