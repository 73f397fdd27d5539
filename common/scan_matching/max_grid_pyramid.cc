#include "common/scan_matching/max_grid_pyramid.h"

#include <algorithm>
#include <optional>
#include <stdexcept>
#include <utility>

#if defined(__SSE2__)
#include <emmintrin.h>
#endif

#include "common/scan_matching/avx2_dispatch.h"

namespace anchormap {
namespace {

#ifdef ANCHORMAP_AVX2_DISPATCH
__attribute__((target("avx2"))) inline __m256i Load32(const uint8_t* p) {
  return _mm256_loadu_si256(reinterpret_cast<const __m256i*>(p));
}

// BuildMaxLevel's inner cells [begin, end) of a row, 32 bytes a step: the maximum of the four
// values; returns the first cell left for the scalar loop. Maxima of bytes are exact in any
// order.
__attribute__((target("avx2"))) int MaxOfFourAvx2(const uint8_t* upper, const uint8_t* lower,
                                                  int half, int begin, int end, uint8_t* dst) {
  int x = begin;
  for (; x + 32 <= end; x += 32) {
    const __m256i up = _mm256_max_epu8(Load32(upper + x - half), Load32(upper + x));
    const __m256i low = _mm256_max_epu8(Load32(lower + x - half), Load32(lower + x));
    _mm256_storeu_si256(reinterpret_cast<__m256i*>(dst + x), _mm256_max_epu8(up, low));
  }
  return x;
}

// The same for floats, eight a step: std::max(a, b) is (a < b ? b : a), which is
// _mm256_max_ps(b, a) (its second operand where they are equal or one is NaN): the same bits.
__attribute__((target("avx2"))) int MaxOfFourAvx2(const float* upper, const float* lower, int half,
                                                  int begin, int end, float* dst) {
  int x = begin;
  for (; x + 8 <= end; x += 8) {
    const __m256 up = _mm256_max_ps(_mm256_loadu_ps(upper + x), _mm256_loadu_ps(upper + x - half));
    const __m256 low = _mm256_max_ps(_mm256_loadu_ps(lower + x), _mm256_loadu_ps(lower + x - half));
    _mm256_storeu_ps(dst + x, _mm256_max_ps(low, up));
  }
  return x;
}
#endif

}  // namespace

template <typename T>
void BuildMaxLevel(const T* below, int width, int height, int half, T* out) {
  // In one pass, row by row: out row y is the max of rows y - half and y below (a row outside
  // reads as zeros), each taken at x - half and x, with the grid's border handled by index
  // ranges rather than a bounds check per value (the same maxima as Value()'s four lookups per
  // cell). Two separable passes wrote every level twice; the pyramid's builds were ~9 % of the
  // server's CPU at 100 robots.
  const int out_width = width + half;
  const std::vector<T> zeros(static_cast<size_t>(std::max(width, 1)), T(0));
  const int both_end = std::max(half, width);
  for (int y = 0; y < height + half; ++y) {
    const T* upper = y < height ? below + static_cast<size_t>(y) * width : zeros.data();
    const T* lower = y - half >= 0 && y - half < height
                         ? below + static_cast<size_t>(y - half) * width
                         : zeros.data();
    T* dst = out + static_cast<size_t>(y) * out_width;
    for (int x = 0; x < half && x < width; ++x)
      dst[x] = std::max(T(0), std::max(upper[x], lower[x]));
    for (int x = width; x < half; ++x) dst[x] = T(0);
    int x_inner = half;
#ifdef ANCHORMAP_AVX2_DISPATCH
    if (CpuHasAvx2()) x_inner = MaxOfFourAvx2(upper, lower, half, half, width, dst);
#endif
    for (int x = x_inner; x < width; ++x) {
      dst[x] = std::max(std::max(upper[x - half], upper[x]), std::max(lower[x - half], lower[x]));
    }
    for (int x = both_end; x < out_width; ++x) {
      dst[x] = std::max(T(0), std::max(upper[x - half], lower[x - half]));
    }
  }
}

template void BuildMaxLevel<float>(const float*, int, int, int, float*);
template void BuildMaxLevel<uint8_t>(const uint8_t*, int, int, int, uint8_t*);

MaxGridPyramid::MaxGridPyramid(const LikelihoodGrid& grid, int num_levels)
    : MaxGridPyramid(LikelihoodGrid(grid), num_levels, /*build_levels=*/true) {}

MaxGridPyramid::MaxGridPyramid(LikelihoodGrid&& grid, int num_levels, bool build_levels)
    : geometry_(grid.geometry()) {
  if (num_levels < 1 || num_levels > 16) {
    throw std::invalid_argument("MaxGridPyramid: num_levels must be in [1, 16]");
  }
  const std::optional<LikelihoodGrid::ValueBounds> bounds = grid.bounds();
  base_ = std::move(grid).TakeValues();
  InitBase(num_levels, bounds);
  if (build_levels) BuildLevels();
}

void MaxGridPyramid::InitBase(int num_levels,
                              const std::optional<LikelihoodGrid::ValueBounds>& bounds) {
  levels_.resize(num_levels);
  Level& base = levels_[0];
  base.offset = 0;
  base.width = geometry_.width;
  base.height = geometry_.height;
  base.values = base_.data();
  levels_built_ = num_levels == 1;
  if (bounds) {  // the grid's own pass found them (a likelihood grid built from a field)
    max_value_ = bounds->max_value;
    exact_sums_ = bounds->exact_sums;
    return;
  }
  // The maximum and the exact-sums test in one pass without branches (most cells are 0), four
  // cells a step with SSE2: the maximum ignores a NaN as std::max(most, value) does (the
  // comparison's second operand is kept) and is otherwise the same in any order.
  constexpr float kExactFloor = 1.0f / 128.0f;  // 2^-7
  float most = 0.0f;
  bool inexact = false;
  size_t i = 0;
  const size_t n = base_.size();
#if defined(__SSE2__)
  __m128 most4 = _mm_setzero_ps();
  __m128 bad4 = _mm_setzero_ps();
  const __m128 zero = _mm_setzero_ps();
  const __m128 floor = _mm_set1_ps(kExactFloor);
  const __m128 one = _mm_set1_ps(1.0f);
  for (; i + 4 <= n; i += 4) {
    const __m128 v = _mm_loadu_ps(base_.data() + i);
    most4 = _mm_max_ps(v, most4);
    const __m128 good =
        _mm_or_ps(_mm_cmpeq_ps(v, zero), _mm_and_ps(_mm_cmpge_ps(v, floor), _mm_cmple_ps(v, one)));
    bad4 = _mm_or_ps(bad4, _mm_andnot_ps(good, _mm_castsi128_ps(_mm_set1_epi32(-1))));
  }
  alignas(16) float lanes[4];
  _mm_store_ps(lanes, most4);
  for (const float lane : lanes) most = std::max(most, lane);
  inexact = _mm_movemask_ps(bad4) != 0;
#endif
  for (; i < n; ++i) {
    const float value = base_[i];
    most = std::max(most, value);
    inexact = inexact || !(value == 0.0f || (value >= kExactFloor && value <= 1.0f));
  }
  max_value_ = most;
  exact_sums_ = !inexact;
}

void MaxGridPyramid::BuildLevels() {
  if (levels_built_) return;
  for (int h = 1; h < num_levels(); ++h) {
    const int half = 1 << (h - 1);
    const Level& p = levels_[h - 1];
    Level& l = levels_[h];
    l.offset = (1 << h) - 1;
    l.width = p.width + half;
    l.height = p.height + half;
    l.owned.reset(new float[static_cast<size_t>(l.width) * l.height]);
    l.values = l.owned.get();
    BuildMaxLevel(p.values, p.width, p.height, half, l.owned.get());
  }
  levels_built_ = true;
}

bool MaxGridPyramid::SameBase(const MaxGridPyramid& other) const {
  return geometry_.width == other.geometry_.width && geometry_.height == other.geometry_.height &&
         geometry_.origin == other.geometry_.origin && base_ == other.base_;
}

}  // namespace anchormap
