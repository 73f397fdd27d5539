#include "common/scan_matching/max_grid_pyramid.h"

#include <algorithm>
#include <stdexcept>

namespace anchormap {

MaxGridPyramid::MaxGridPyramid(const LikelihoodGrid& grid, int num_levels)
    : geometry_(grid.geometry()) {
  if (num_levels < 1 || num_levels > 16) {
    throw std::invalid_argument("MaxGridPyramid: num_levels must be in [1, 16]");
  }
  levels_.resize(num_levels);
  Level& base = levels_[0];
  base.offset = 0;
  base.width = geometry_.width;
  base.height = geometry_.height;
  base.values.resize(geometry_.num_cells());
  for (int iy = 0; iy < geometry_.height; ++iy) {
    for (int ix = 0; ix < geometry_.width; ++ix) {
      base.values[geometry_.Index(ix, iy)] = grid.Value(ix, iy);
    }
  }
  for (int h = 1; h < num_levels; ++h) {
    const int half = 1 << (h - 1);
    Level& l = levels_[h];
    l.offset = (1 << h) - 1;
    l.width = geometry_.width + l.offset;
    l.height = geometry_.height + l.offset;
    l.values.assign(static_cast<size_t>(l.width) * l.height, 0.0f);
    for (int y = 0; y < l.height; ++y) {
      const int iy = y - l.offset;
      for (int x = 0; x < l.width; ++x) {
        const int ix = x - l.offset;
        l.values[static_cast<size_t>(y) * l.width + x] =
            std::max({Value(h - 1, ix, iy), Value(h - 1, ix + half, iy),
                      Value(h - 1, ix, iy + half), Value(h - 1, ix + half, iy + half)});
      }
    }
  }
}

}  // namespace anchormap
