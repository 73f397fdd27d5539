#include "common/scan_matching/max_grid_pyramid.h"

#include <algorithm>
#include <random>
#include <utility>
#include <vector>

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

void ExpectBruteForceBlockMaxima(const LikelihoodGrid& grid, int num_levels, uint64_t seed) {
  const MaxGridPyramid pyramid(grid, num_levels);
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

TEST(MaxGridPyramidTest, EveryLevelEqualsBruteForceBlockMaxima) {
  for (uint64_t seed = 1; seed <= 5; ++seed) {
    const LikelihoodGrid grid =
        RandomGrid(13 + static_cast<int>(seed), 9 + 2 * static_cast<int>(seed), seed);
    ExpectBruteForceBlockMaxima(grid, 5, seed);
  }
  // Rows wide enough for several vector steps of the levels' build, and a remainder.
  ExpectBruteForceBlockMaxima(RandomGrid(83, 21, 6), 5, 6);
}

// Grids narrower than the largest blocks (the levels' borders are most of them).
TEST(MaxGridPyramidTest, GridsSmallerThanTheBlocksEqualBruteForce) {
  const std::vector<std::pair<int, int>> sizes = {{1, 1}, {1, 7}, {7, 1}, {3, 40}, {40, 2}};
  uint64_t seed = 10;
  for (const auto& [width, height] : sizes) {
    ExpectBruteForceBlockMaxima(RandomGrid(width, height, seed), 7, seed);
    ++seed;
  }
}

}  // namespace
}  // namespace anchormap
