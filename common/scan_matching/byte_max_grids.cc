#include "common/scan_matching/byte_max_grids.h"

#include <cmath>
#include <cstring>
#include <stdexcept>
#include <vector>

#include "common/scan_matching/avx2_dispatch.h"

namespace anchormap {

namespace {

// ceil(kScale * v), in double: a float times 255 is exact there, so the byte is never below.
uint8_t RoundedUp(float value) {
  return static_cast<uint8_t>(std::ceil(static_cast<double>(value) * ByteMaxGrids::kScale));
}

#ifdef ANCHORMAP_AVX2_DISPATCH
// RoundedUp of values [0, n - n % 4), four at a time (the same double products and ceilings);
// returns how many were done.
__attribute__((target("avx2"))) size_t RoundUpAvx2(const float* values, size_t n, uint8_t* out) {
  const __m256d scale = _mm256_set1_pd(ByteMaxGrids::kScale);
  size_t i = 0;
  for (; i + 4 <= n; i += 4) {
    const __m256d up =
        _mm256_ceil_pd(_mm256_mul_pd(_mm256_cvtps_pd(_mm_loadu_ps(values + i)), scale));
    const __m128i words = _mm256_cvttpd_epi32(up);  // whole numbers in [0, 255]
    const __m128i bytes = _mm_packus_epi16(_mm_packus_epi32(words, words), _mm_setzero_si128());
    const int packed = _mm_cvtsi128_si32(bytes);
    std::memcpy(out + i, &packed, 4);
  }
  return i;
}
#endif

}  // namespace

ByteMaxGrids::ByteMaxGrids(const MaxGridPyramid& pyramid) {
  if (!pyramid.exact_sums()) {
    throw std::invalid_argument("ByteMaxGrids: the pyramid's values must lie in [0, 1]");
  }
  levels_.resize(static_cast<size_t>(pyramid.num_levels()));
  const MaxGridPyramid::LevelView base = pyramid.level(0);
  const size_t base_cells = static_cast<size_t>(base.width) * static_cast<size_t>(base.height);
  std::vector<uint8_t> below(base_cells);
  size_t i = 0;
#ifdef ANCHORMAP_AVX2_DISPATCH
  if (CpuHasAvx2()) i = RoundUpAvx2(base.values, base_cells, below.data());
#endif
  for (; i < base_cells; ++i) below[i] = RoundedUp(base.values[i]);
  const uint8_t* previous = below.data();
  int width = base.width;
  int height = base.height;
  for (int h = 1; h < pyramid.num_levels(); ++h) {
    const int half = 1 << (h - 1);
    Level& level = levels_[static_cast<size_t>(h)];
    level.offset = (1 << h) - 1;
    level.width = width + half;
    level.height = height + half;
    const size_t cells = static_cast<size_t>(level.width) * static_cast<size_t>(level.height);
    level.values.reset(new uint8_t[cells + 3]);
    BuildMaxLevel(previous, width, height, half, level.values.get());
    for (size_t i = cells; i < cells + 3; ++i) level.values[i] = 0;
    previous = level.values.get();
    width = level.width;
    height = level.height;
  }
  max_value_ = RoundedUp(pyramid.max_value());
}

ByteMaxGrids::LevelView ByteMaxGrids::level(int h) const {
  const Level& l = levels_[static_cast<size_t>(h)];
  return {l.offset, l.width, l.height, l.values.get()};
}

}  // namespace anchormap
