#include "common/scan_matching/byte_max_grids.h"

#include <algorithm>
#include <cmath>
#include <cstdlib>
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

// RoundedUp of values [0, n).
void RoundUp(const float* values, size_t n, uint8_t* out) {
  size_t i = 0;
#ifdef ANCHORMAP_AVX2_DISPATCH
  if (CpuHasAvx2()) i = RoundUpAvx2(values, n, out);
#endif
  for (; i < n; ++i) out[i] = RoundedUp(values[i]);
}

// Calls run(first, last) for each run of consecutive nonzero entries of a row of `n` tiles.
template <typename Run>
void ForEachRun(const uint8_t* tiles, int n, Run&& run) {
  for (int c = 0; c < n;) {
    if (!tiles[c]) {
      ++c;
      continue;
    }
    const int first = c;
    while (c < n && tiles[c]) ++c;
    run(first, c - 1);
  }
}

}  // namespace

ByteMaxGrids::ByteMaxGrids(const MaxGridPyramid& pyramid) {
  if (!pyramid.exact_sums()) {
    throw std::invalid_argument("ByteMaxGrids: the pyramid's values must lie in [0, 1]");
  }
  const MaxGridPyramid::LevelView base = pyramid.level(0);
  const size_t base_cells = static_cast<size_t>(base.width) * static_cast<size_t>(base.height);
  std::vector<uint8_t> below(base_cells);
  RoundUp(base.values, base_cells, below.data());
  BuildLevels(below.data(), base.width, base.height, pyramid.num_levels());
  max_value_ = RoundedUp(pyramid.max_value());
}

ByteMaxGrids::ByteMaxGrids(const MaxGridPyramid& pyramid, const NonzeroTiles& nonzero) {
  if (!pyramid.exact_sums()) {
    throw std::invalid_argument("ByteMaxGrids: the pyramid's values must lie in [0, 1]");
  }
  const MaxGridPyramid::LevelView base = pyramid.level(0);
  const int shift = nonzero.tile_shift;
  const int tile = 1 << shift;
  if (shift < 0 || shift > 16 || nonzero.tiles_width != (base.width + tile - 1) >> shift) {
    throw std::invalid_argument("ByteMaxGrids: the tiles must cover the grid");
  }
  // Level 0 rounded up on its nonzero tiles (whole runs of them a row at a time), 0 elsewhere.
  const size_t base_cells = static_cast<size_t>(base.width) * static_cast<size_t>(base.height);
  std::vector<uint8_t> below(base_cells, 0);
  for (int r = 0; r < (base.height + tile - 1) >> shift; ++r) {
    ForEachRun(nonzero.tiles + static_cast<size_t>(r) * nonzero.tiles_width, nonzero.tiles_width,
               [&](int first, int last) {
                 const int x0 = first << shift;
                 const int x1 = std::min((last + 1) << shift, base.width);
                 for (int y = r << shift; y < std::min((r + 1) << shift, base.height); ++y) {
                   const size_t row = static_cast<size_t>(y) * base.width;
                   RoundUp(base.values + row + x0, static_cast<size_t>(x1 - x0),
                           below.data() + row + x0);
                 }
               });
  }
  BuildLevels(below.data(), base.width, base.height, pyramid.num_levels());
  max_value_ = RoundedUp(pyramid.max_value());
}

void ByteMaxGrids::BuildLevels(const uint8_t* base, int width, int height, int num_levels) {
  levels_.resize(static_cast<size_t>(num_levels));
  const uint8_t* previous = base;
  for (int h = 1; h < num_levels; ++h) {
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
}

ByteMaxGrids::LevelView ByteMaxGrids::level(int h) const {
  const Level& l = levels_[static_cast<size_t>(h)];
  return {l.offset, l.width, l.height, l.values.get()};
}

}  // namespace anchormap
