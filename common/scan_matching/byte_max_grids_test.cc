#include "common/scan_matching/byte_max_grids.h"

#include <cmath>
#include <random>
#include <stdexcept>
#include <utility>
#include <vector>

#include <gtest/gtest.h>

namespace anchormap {
namespace {

TEST(ByteMaxGridsTest, EveryByteIsItsFloatRoundedUpToA255th) {
  // A grid of exact values (0, 2^-7, 1 and random ones between): on every level above 0 each
  // byte b is the least whole number with b >= 255 v, the level's geometry is the pyramid's,
  // and the three bytes past the last cell read 0.
  std::mt19937_64 rng(3);
  std::uniform_real_distribution<float> unit(1.0f / 128.0f, 1.0f);
  GridGeometry g;
  g.width = 37;
  g.height = 29;
  std::vector<float> values(g.num_cells(), 0.0f);
  for (size_t i = 0; i < values.size(); ++i) {
    values[i] = i % 5 == 0 ? 0.0f : i % 7 == 0 ? 1.0f / 128.0f : i % 11 == 0 ? 1.0f : unit(rng);
  }
  const MaxGridPyramid pyramid(LikelihoodGrid(g, values), 5);
  ASSERT_TRUE(pyramid.exact_sums());
  const ByteMaxGrids bytes(pyramid);
  ASSERT_EQ(bytes.num_levels(), 5);
  EXPECT_EQ(bytes.max_value(), 255);
  for (int h = 1; h < 5; ++h) {
    const MaxGridPyramid::LevelView floats = pyramid.level(h);
    const ByteMaxGrids::LevelView level = bytes.level(h);
    ASSERT_EQ(level.offset, floats.offset);
    ASSERT_EQ(level.width, floats.width);
    ASSERT_EQ(level.height, floats.height);
    const size_t cells = static_cast<size_t>(level.width) * static_cast<size_t>(level.height);
    for (size_t i = 0; i < cells; ++i) {
      const double scaled = 255.0 * static_cast<double>(floats.values[i]);
      ASSERT_GE(level.values[i], scaled) << "level " << h << " cell " << i;
      ASSERT_LT(level.values[i] - 1.0, scaled) << "level " << h << " cell " << i;
    }
    for (size_t i = cells; i < cells + 3; ++i) EXPECT_EQ(level.values[i], 0);
  }
}

TEST(ByteMaxGridsTest, GridsSmallerThanTheBlocksRoundTheFloatLevelsUp) {
  // The bytes are built from level 0 by their own recursion: on grids narrower than the
  // largest blocks (the levels' borders are most of them) every byte is still its float
  // level's value rounded up.
  std::mt19937_64 rng(5);
  std::uniform_real_distribution<float> unit(1.0f / 128.0f, 1.0f);
  for (const auto& [width, height] : {std::pair{1, 1}, {1, 7}, {7, 1}, {3, 40}, {40, 2}}) {
    GridGeometry g;
    g.width = width;
    g.height = height;
    std::vector<float> values(g.num_cells(), 0.0f);
    for (float& v : values) v = unit(rng) < 0.4f ? unit(rng) : 0.0f;
    const MaxGridPyramid pyramid(LikelihoodGrid(g, values), 7);
    const ByteMaxGrids bytes(pyramid);
    for (int h = 1; h < 7; ++h) {
      const MaxGridPyramid::LevelView floats = pyramid.level(h);
      const ByteMaxGrids::LevelView level = bytes.level(h);
      const size_t cells = static_cast<size_t>(level.width) * static_cast<size_t>(level.height);
      ASSERT_EQ(cells, static_cast<size_t>(floats.width) * static_cast<size_t>(floats.height));
      for (size_t i = 0; i < cells; ++i) {
        ASSERT_EQ(level.values[i], std::ceil(255.0 * static_cast<double>(floats.values[i])))
            << width << "x" << height << " level " << h << " cell " << i;
      }
    }
  }
}

TEST(ByteMaxGridsTest, RefusesAPyramidWhoseSumsAreNotExact) {
  GridGeometry g;
  g.width = 4;
  g.height = 4;
  std::vector<float> values(g.num_cells(), 0.001f);  // below 2^-7
  const MaxGridPyramid pyramid(LikelihoodGrid(g, values), 2);
  ASSERT_FALSE(pyramid.exact_sums());
  EXPECT_THROW(ByteMaxGrids{pyramid}, std::invalid_argument);
}

}  // namespace
}  // namespace anchormap
