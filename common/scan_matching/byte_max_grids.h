#pragma once
// The max-grid pyramid's levels 1 and up as bytes, each value rounded up to a whole 1/255: the
// bounds of a global search's inner nodes, summed in integers and read from a quarter of the
// floats' memory (issue 11: the global searches' point sums were ~40 % of the FR079 replay
// split in three). Rounded up, every byte level still bounds the likelihood over its blocks
// (and a coarser level bounds a finer one), so branch and bound finds the same best pose with
// them; level 0, the leaves' own scores, stays in floats.

#include <cstdint>
#include <memory>
#include <vector>

#include "common/scan_matching/max_grid_pyramid.h"

namespace anchormap {

class ByteMaxGrids {
 public:
  // A byte holds round-up multiples of 1 / kScale.
  static constexpr int kScale = 255;

  // Precondition: pyramid.exact_sums() (every value in [0, 1]). Built from the pyramid's level 0
  // alone (its float levels above need not be built): level 0 rounded up, then the pyramid's
  // recursion on the bytes. Rounding up is monotone, so the max of rounded values is the
  // rounded max: each byte is its float level's value rounded up, as if converted from it.
  explicit ByteMaxGrids(const MaxGridPyramid& pyramid);
  // Where level 0 may be nonzero: tiles of 2^tile_shift x 2^tile_shift cells, row-major
  // (tiles_width = ceil(width / 2^tile_shift) a row, ceil(height / 2^tile_shift) rows), 0 where
  // every cell of the tile is 0 (a reference's likelihood is nonzero only near its walls,
  // ReferenceField::reached_tiles).
  struct NonzeroTiles {
    int tile_shift = 0;
    int tiles_width = 0;
    const uint8_t* tiles = nullptr;
  };
  // The same bytes, level 0 rounded up on those tiles alone (the others are 0): ~12 % of a
  // reference's tiles are near a wall, and rounding every cell was ~40 % of the bytes' build
  // at 100 robots (the likelihood grid's floats read again, long after the reference's build).
  ByteMaxGrids(const MaxGridPyramid& pyramid, const NonzeroTiles& nonzero);

  int num_levels() const { return static_cast<int>(levels_.size()); }
  // Level h >= 1 as MaxGridPyramid::level(h) stores it (same offset, width and height), each
  // value ceil(kScale * v). Three bytes past the last cell are readable (four-byte gathers).
  struct LevelView {
    int offset;
    int width;
    int height;
    const uint8_t* values;
  };
  LevelView level(int h) const;
  // ceil(kScale * pyramid.max_value()): no point scores more on any level.
  int max_value() const { return max_value_; }

 private:
  // Levels 1 and up from level 0 rounded up (`base`, width x height).
  void BuildLevels(const uint8_t* base, int width, int height, int num_levels);
  struct Level {
    int offset = 0;
    int width = 0;
    int height = 0;
    std::unique_ptr<uint8_t[]> values;
  };
  std::vector<Level> levels_;  // [0] unused: the leaves read the floats
  int max_value_ = 0;
};

}  // namespace anchormap
