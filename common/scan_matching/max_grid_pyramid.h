#pragma once
// Precomputed max-grids for branch and bound (the idea of Hess, Kohler, Rapp and Andor, "Real-
// time loop closure in 2D LIDAR SLAM", ICRA 2016): level h holds, for every cell (ix, iy), the
// maximum of the likelihood grid over the 2^h x 2^h block of cells [ix, ix + 2^h) x
// [iy, iy + 2^h) (cells outside the grid count 0). A query scored on level h at translation
// offset (dx, dy) is then an upper bound of its score at every offset in
// [dx, dx + 2^h) x [dy, dy + 2^h), which is what lets a search skip whole blocks.
//
// Level h is stored for ix in [-(2^h - 1), width) (blocks that reach into the grid from the
// left or below) and built from level h - 1 by the max of four shifted values, O(1) per cell
// (two separable passes).

#include <cstdint>
#include <memory>
#include <optional>
#include <vector>

#include "common/scan_matching/likelihood_grid.h"

namespace anchormap {

class MaxGridPyramid {
 public:
  // Precondition: num_levels >= 1. Level 0 is the grid itself (copied).
  MaxGridPyramid(const LikelihoodGrid& grid, int num_levels);
  // The same pyramid taking the grid's values as level 0 (no copy); with build_levels false
  // only level 0 is built until BuildLevels() (a search bounded on ByteMaxGrids reads level 0
  // alone: the float levels above cost four times the bytes' memory and were a third of a
  // reference's build at 100 robots).
  MaxGridPyramid(LikelihoodGrid&& grid, int num_levels, bool build_levels);

  // Builds levels 1 and up when they are not yet (not thread-safe: ScanReference calls it once).
  void BuildLevels();
  bool levels_built() const { return levels_built_; }

  int num_levels() const { return static_cast<int>(levels_.size()); }
  const GridGeometry& geometry() const { return geometry_; }
  // One level's storage: Value(level, ix, iy) is values[(iy + offset) * width + ix + offset]
  // inside [0, width) x [0, height) of the stored indices, 0 outside (the search's inner loop
  // reads it directly). Levels above 0 only once built.
  struct LevelView {
    int offset;
    int width;
    int height;
    const float* values;
  };
  LevelView level(int h) const {
    const Level& l = levels_[h];
    return {l.offset, l.width, l.height, l.values};
  }
  // The largest value of the grid (of every level): no query point scores more.
  float max_value() const { return max_value_; }
  // True when every value is 0 or in [2^-7, 1]: each is then a whole multiple of 2^-30 (a
  // float's last bit there is 2^-30 or more), so that a double sum of fewer than 2^23 of them
  // is exact in any order. A likelihood grid cut at 3 sigma (values >= exp(-4.5)) qualifies.
  bool exact_sums() const { return exact_sums_; }
  // Max over the block [ix, ix + 2^level) x [iy, iy + 2^level); 0 when it misses the grid.
  float Value(int level, int ix, int iy) const {
    const Level& l = levels_[level];
    const int x = ix + l.offset;
    const int y = iy + l.offset;
    if (x < 0 || y < 0 || x >= l.width || y >= l.height) return 0.0f;
    return l.values[static_cast<size_t>(y) * l.width + x];
  }
  // The same cells (extent and origin) holding the same level 0, exactly.
  bool SameBase(const MaxGridPyramid& other) const;

 private:
  struct Level {
    int offset = 0;  // 2^h - 1
    int width = 0;
    int height = 0;
    const float* values = nullptr;  // base_ for level 0, else owned
    // Every cell is written by the build: no zero fill first (the fill and the first touch
    // of the pages were most of a reference's build time once the maxima were cheap).
    std::unique_ptr<float[]> owned;
  };
  // Level 0's view, its largest value and exact-sums test (from `bounds` when the grid knows
  // them, else in a pass over its values).
  void InitBase(int num_levels, const std::optional<LikelihoodGrid::ValueBounds>& bounds);

  GridGeometry geometry_;
  std::vector<float> base_;
  std::vector<Level> levels_;
  float max_value_ = 0.0f;
  bool exact_sums_ = true;
  bool levels_built_ = false;
};

// One level of block maxima from the level below (MaxGridPyramid's recursion, for floats and
// for ByteMaxGrids' bytes): `below` is width x height, `half` = 2^(h-1), and `out` receives
// (width + half) x (height + half) values, out(x, y) = max of below at (x - half | x,
// y - half | y), 0 outside.
template <typename T>
void BuildMaxLevel(const T* below, int width, int height, int half, T* out);

}  // namespace anchormap
