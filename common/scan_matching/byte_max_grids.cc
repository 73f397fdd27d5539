#include "common/scan_matching/byte_max_grids.h"

#include <cmath>
#include <stdexcept>

namespace anchormap {

namespace {

// ceil(kScale * v), in double: a float times 255 is exact there, so the byte is never below.
uint8_t RoundedUp(float value) {
  return static_cast<uint8_t>(std::ceil(static_cast<double>(value) * ByteMaxGrids::kScale));
}

}  // namespace

ByteMaxGrids::ByteMaxGrids(const MaxGridPyramid& pyramid) {
  if (!pyramid.exact_sums()) {
    throw std::invalid_argument("ByteMaxGrids: the pyramid's values must lie in [0, 1]");
  }
  levels_.resize(static_cast<size_t>(pyramid.num_levels()));
  for (int h = 1; h < pyramid.num_levels(); ++h) {
    const MaxGridPyramid::LevelView source = pyramid.level(h);
    Level& level = levels_[static_cast<size_t>(h)];
    level.offset = source.offset;
    level.width = source.width;
    level.height = source.height;
    const size_t cells = static_cast<size_t>(source.width) * static_cast<size_t>(source.height);
    level.values.reset(new uint8_t[cells + 3]);
    for (size_t i = 0; i < cells; ++i) level.values[i] = RoundedUp(source.values[i]);
    for (size_t i = cells; i < cells + 3; ++i) level.values[i] = 0;
  }
  max_value_ = RoundedUp(pyramid.max_value());
}

ByteMaxGrids::LevelView ByteMaxGrids::level(int h) const {
  const Level& l = levels_[static_cast<size_t>(h)];
  return {l.offset, l.width, l.height, l.values.get()};
}

}  // namespace anchormap
