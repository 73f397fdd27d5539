#include "common/scan_matching/byte_max_grids.h"

#include <algorithm>
#include <cmath>
#include <random>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include <gtest/gtest.h>

#include "common/scan_matching/scan_reference.h"

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

// Every level's bytes (and the three past them) equal, byte for byte.
void ExpectSameBytes(const ByteMaxGrids& expected, const ByteMaxGrids& actual,
                     const std::string& what) {
  ASSERT_EQ(actual.num_levels(), expected.num_levels()) << what;
  EXPECT_EQ(actual.max_value(), expected.max_value()) << what;
  for (int h = 1; h < expected.num_levels(); ++h) {
    const ByteMaxGrids::LevelView e = expected.level(h), a = actual.level(h);
    ASSERT_EQ(a.offset, e.offset) << what;
    ASSERT_EQ(a.width, e.width) << what;
    ASSERT_EQ(a.height, e.height) << what;
    const size_t cells = static_cast<size_t>(e.width) * static_cast<size_t>(e.height) + 3;
    for (size_t i = 0; i < cells; ++i) {
      ASSERT_EQ(a.values[i], e.values[i]) << what << " level " << h << " cell " << i;
    }
  }
}

TEST(ByteMaxGridsTest, RoundedOnTheNonzeroTilesAloneTheBytesAreTheSame) {
  // Grids of many shapes (narrower than the largest blocks, sides not multiples of the tiles)
  // whose nonzero values lie in random tiles (a tenth to all of them, and none), of 8 and of
  // 4 cells, some of those tiles all zero: the bytes of level 0 rounded up on those tiles
  // alone equal those of every cell rounded up, on every level.
  std::mt19937_64 rng(17);
  std::uniform_real_distribution<float> unit(1.0f / 128.0f, 1.0f);
  int compared = 0;
  for (const auto& [width, height] :
       {std::pair{1, 1}, {5, 3}, {8, 8}, {9, 17}, {40, 2}, {64, 64}, {77, 123}, {203, 150}}) {
    for (const int shift : {3, 2}) {
      for (const double density : {0.0, 0.1, 0.3, 1.0}) {
        GridGeometry g;
        g.width = width;
        g.height = height;
        const int tile = 1 << shift;
        const int columns = (width + tile - 1) >> shift;
        const int rows = (height + tile - 1) >> shift;
        std::vector<uint8_t> tiles(static_cast<size_t>(columns) * rows, 0);
        std::uniform_real_distribution<double> draw(0.0, 1.0);
        for (uint8_t& t : tiles) t = draw(rng) < density ? 1 : 0;
        std::vector<float> values(g.num_cells(), 0.0f);
        for (int y = 0; y < height; ++y) {
          for (int x = 0; x < width; ++x) {
            if (!tiles[static_cast<size_t>(y >> shift) * columns + (x >> shift)]) continue;
            if (draw(rng) < 0.5) values[static_cast<size_t>(y) * width + x] = unit(rng);
          }
        }
        const MaxGridPyramid pyramid(LikelihoodGrid(g, values), 7);
        ASSERT_TRUE(pyramid.exact_sums());
        const ByteMaxGrids dense(pyramid);
        const ByteMaxGrids sparse(pyramid,
                                  ByteMaxGrids::NonzeroTiles{shift, columns, tiles.data()});
        ExpectSameBytes(dense, sparse,
                        std::to_string(width) + "x" + std::to_string(height) + " shift " +
                            std::to_string(shift) + " density " + std::to_string(density));
        ++compared;
      }
    }
  }
  EXPECT_EQ(compared, 64);
}

TEST(ByteMaxGridsTest, AReferencesBytesAreThoseOfEveryCell) {
  // Two rooms' walls seen from inside (a reference as the server builds one): the bytes it
  // builds from the field's reached tiles equal those of every cell, and most of its tiles
  // are empty.
  std::vector<PointCloud> scans(2);
  for (int room = 0; room < 2; ++room) {
    const double cx = room * 14.0, cy = room * 3.0;
    for (int i = 0; i < 720; ++i) {
      const double t = 2.0 * M_PI * i / 720.0;
      const double c = std::cos(t), s = std::sin(t);
      const double range =
          std::min(6.0 / std::max(std::abs(c), 1e-9), 4.0 / std::max(std::abs(s), 1e-9));
      scans[static_cast<size_t>(room)].push_back({cx + range * c, cy + range * s});
    }
  }
  const ScanReference reference(scans, ScanReferenceOptions{});
  const ByteMaxGrids* sparse = reference.byte_bounds();
  ASSERT_NE(sparse, nullptr);
  const ByteMaxGrids dense(reference.base());
  ExpectSameBytes(dense, *sparse, "two rooms");
  const std::vector<uint8_t>& reached = reference.field().reached_tiles();
  EXPECT_LT(std::count(reached.begin(), reached.end(), 1), reached.size() / 3);
  EXPECT_GT(sparse->max_value(), 200);  // a cell centre near a wall
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
