#include "common/scan_matching/lattice_search.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <memory>
#include <optional>
#include <stdexcept>
#include <vector>

#include "common/scan_matching/avx2_dispatch.h"
#if !defined(ANCHORMAP_AVX2_DISPATCH) && defined(__SSE2__)
#include <emmintrin.h>
#endif

namespace anchormap {

Pose2 LatticeToPose(const SearchWindow& window, double resolution, const LatticePose& lattice) {
  return Pose2(window.center.x() + lattice.dx * resolution,
               window.center.y() + lattice.dy * resolution,
               window.center.theta() + lattice.k * window.angle_step_rad);
}

double AngleStepForRange(double resolution_m, double max_range_m) {
  if (!(max_range_m > resolution_m)) return 0.1;
  return std::min(0.1, 2.0 * std::asin(0.5 * resolution_m / max_range_m));
}

namespace {

#ifdef ANCHORMAP_AVX2_DISPATCH
// The cells of points [0, n - n % 4) at one heading, four at a time: R p + t as Eigen computes
// it ((R00 x + R01 y) + t), CellOf's quotients, and floor as the SSE2 path takes it (truncation,
// one less where that is above the quotient): the same cells. Widens [min, max] to hold them.
__attribute__((target("avx2"))) void DiscretiseHeadingAvx2(
    const double* px, const double* py, size_t n, const Eigen::Matrix2d& R,
    const Eigen::Vector2d& t, const GridGeometry& geometry, int32_t* xs, int32_t* ys,
    Eigen::Vector2i* min, Eigen::Vector2i* max) {
  const __m256d r00 = _mm256_set1_pd(R(0, 0));
  const __m256d r01 = _mm256_set1_pd(R(0, 1));
  const __m256d r10 = _mm256_set1_pd(R(1, 0));
  const __m256d r11 = _mm256_set1_pd(R(1, 1));
  const __m256d tx = _mm256_set1_pd(t.x());
  const __m256d ty = _mm256_set1_pd(t.y());
  const __m256d origin_x = _mm256_set1_pd(geometry.origin.x());
  const __m256d origin_y = _mm256_set1_pd(geometry.origin.y());
  const __m256d resolution = _mm256_set1_pd(geometry.resolution);
  __m128i min_x = _mm_set1_epi32(min->x());
  __m128i min_y = _mm_set1_epi32(min->y());
  __m128i max_x = _mm_set1_epi32(max->x());
  __m128i max_y = _mm_set1_epi32(max->y());
  for (size_t i = 0; i + 4 <= n; i += 4) {
    const __m256d x = _mm256_loadu_pd(px + i);
    const __m256d y = _mm256_loadu_pd(py + i);
    const __m256d qx =
        _mm256_add_pd(_mm256_add_pd(_mm256_mul_pd(r00, x), _mm256_mul_pd(r01, y)), tx);
    const __m256d qy =
        _mm256_add_pd(_mm256_add_pd(_mm256_mul_pd(r10, x), _mm256_mul_pd(r11, y)), ty);
    const __m256d ux = _mm256_div_pd(_mm256_sub_pd(qx, origin_x), resolution);
    const __m256d uy = _mm256_div_pd(_mm256_sub_pd(qy, origin_y), resolution);
    const __m128i truncated_x = _mm256_cvttpd_epi32(ux);
    const __m128i truncated_y = _mm256_cvttpd_epi32(uy);
    // The comparison's all-ones lanes (64 bits) narrowed to 32: -1 where truncation is above.
    const __m128i above_x = _mm256_cvtpd_epi32(_mm256_and_pd(
        _mm256_cmp_pd(_mm256_cvtepi32_pd(truncated_x), ux, _CMP_GT_OQ), _mm256_set1_pd(-1.0)));
    const __m128i above_y = _mm256_cvtpd_epi32(_mm256_and_pd(
        _mm256_cmp_pd(_mm256_cvtepi32_pd(truncated_y), uy, _CMP_GT_OQ), _mm256_set1_pd(-1.0)));
    const __m128i cx = _mm_add_epi32(truncated_x, above_x);
    const __m128i cy = _mm_add_epi32(truncated_y, above_y);
    _mm_storeu_si128(reinterpret_cast<__m128i*>(xs + i), cx);
    _mm_storeu_si128(reinterpret_cast<__m128i*>(ys + i), cy);
    min_x = _mm_min_epi32(min_x, cx);
    min_y = _mm_min_epi32(min_y, cy);
    max_x = _mm_max_epi32(max_x, cx);
    max_y = _mm_max_epi32(max_y, cy);
  }
  alignas(16) int32_t lanes[4][4];
  _mm_store_si128(reinterpret_cast<__m128i*>(lanes[0]), min_x);
  _mm_store_si128(reinterpret_cast<__m128i*>(lanes[1]), min_y);
  _mm_store_si128(reinterpret_cast<__m128i*>(lanes[2]), max_x);
  _mm_store_si128(reinterpret_cast<__m128i*>(lanes[3]), max_y);
  for (int j = 0; j < 4; ++j) {
    *min = min->cwiseMin(Eigen::Vector2i(lanes[0][j], lanes[1][j]));
    *max = max->cwiseMax(Eigen::Vector2i(lanes[2][j], lanes[3][j]));
  }
}
#endif

}  // namespace

DiscretisedQuery::DiscretisedQuery(const PointCloud& query, const SearchWindow& window,
                                   const GridGeometry& geometry)
    : half_angles_(window.half_angles), num_points_(query.size()) {
  const size_t headings = static_cast<size_t>(2 * window.half_angles + 1);
  boxes_.resize(headings);
  // At least one entry: a heading of an empty query points at an array, not at null.
  // Default-initialised (not zeroed): every heading below writes all its cells.
  xs_.reset(new int32_t[std::max<size_t>(1, headings * query.size())]);
  ys_.reset(new int32_t[std::max<size_t>(1, headings * query.size())]);
#ifdef ANCHORMAP_AVX2_DISPATCH
  // The points' x and y apart, for four at a time.
  const bool avx2 = CpuHasAvx2();
  std::vector<double> px;
  std::vector<double> py;
  if (avx2) {
    px.reserve(query.size());
    py.reserve(query.size());
    for (const Eigen::Vector2d& p : query) {
      px.push_back(p.x());
      py.push_back(p.y());
    }
  }
#endif
#if defined(__SSE2__)
  const __m128d origin = _mm_set_pd(geometry.origin.y(), geometry.origin.x());
  const __m128d resolution = _mm_set1_pd(geometry.resolution);
#endif
  for (int k = -window.half_angles; k <= window.half_angles; ++k) {
    const Pose2 pose(window.center.x(), window.center.y(),
                     window.center.theta() + k * window.angle_step_rad);
    const Eigen::Matrix2d R = pose.rotation();
    const Eigen::Vector2d t = pose.translation();
    int32_t* xs = xs_.get() + Offset(k);
    int32_t* ys = ys_.get() + Offset(k);
    Box& box = boxes_[k + half_angles_];
    box.min.setConstant(std::numeric_limits<int>::max());
    box.max.setConstant(std::numeric_limits<int>::min());
    size_t i = 0;
#ifdef ANCHORMAP_AVX2_DISPATCH
    if (avx2) {
      DiscretiseHeadingAvx2(px.data(), py.data(), query.size(), R, t, geometry, xs, ys, &box.min,
                            &box.max);
      i = query.size() - query.size() % 4;
    }
#endif
    for (; i < query.size(); ++i) {
      const Eigen::Vector2d q = R * query[i] + t;
#if defined(__SSE2__)
      // GridGeometry::CellOf, both axes in one division (the same IEEE quotients) and floor by
      // truncation corrected below zero (exact for cells within +-2^31).
      const __m128d u = _mm_div_pd(_mm_sub_pd(_mm_set_pd(q.y(), q.x()), origin), resolution);
      const __m128i truncated = _mm_cvttpd_epi32(u);
      const __m128d above = _mm_cmpgt_pd(_mm_cvtepi32_pd(truncated), u);
      const __m128i minus_one = _mm_shuffle_epi32(_mm_castpd_si128(above), _MM_SHUFFLE(2, 0, 2, 0));
      const __m128i cell = _mm_add_epi32(truncated, minus_one);
      const Eigen::Vector2i c(_mm_cvtsi128_si32(cell), _mm_cvtsi128_si32(_mm_srli_si128(cell, 4)));
#else
      const Eigen::Vector2i c = geometry.CellOf(q);
#endif
      xs[i] = c.x();
      ys[i] = c.y();
      box.min = box.min.cwiseMin(c);
      box.max = box.max.cwiseMax(c);
    }
  }
}

double ScoreOnLevel(const MaxGridPyramid& grids, int level, const DiscretisedQuery& query, int k,
                    int dx, int dy) {
  return ScoreOnLevelAbove(grids, level, query, k, dx, dy,
                           -std::numeric_limits<double>::infinity());
}

namespace {

// Points summed between two looks at whether the rest can still lift the mean above the floor.
// Each look costs a horizontal sum and a branch: on FR079's global searches 64 took 4-5 % less
// time than 32 (16: 12 % more, 96 and 128 about as 64), the same nodes scored.
constexpr size_t kChunk = 64;

// The sum of the level's values at cells[begin, end) shifted by (x0, y0) in stored indices:
// `Inside` when every shifted cell lies within the stored level (no bounds checks), `Exact`
// when the values' sums are exact in any order (MaxGridPyramid::exact_sums: four independent
// sums, the same double), in order otherwise (the same rounding as one running sum).
template <bool Inside, bool Exact>
double SumCells(const MaxGridPyramid::LevelView& l, const int32_t* xs, const int32_t* ys,
                size_t begin, size_t end, int x0, int y0, double sum) {
  auto value = [&l, xs, ys, x0, y0](size_t i) -> double {
    const int x = xs[i] + x0;
    const int y = ys[i] + y0;
    if (!Inside && (static_cast<unsigned>(x) >= static_cast<unsigned>(l.width) ||
                    static_cast<unsigned>(y) >= static_cast<unsigned>(l.height))) {
      return 0.0;
    }
    return l.values[static_cast<size_t>(y) * static_cast<size_t>(l.width) + static_cast<size_t>(x)];
  };
  size_t i = begin;
  if (Exact) {
    double s1 = 0.0, s2 = 0.0, s3 = 0.0;
    for (; i + 4 <= end; i += 4) {
      sum += value(i);
      s1 += value(i + 1);
      s2 += value(i + 2);
      s3 += value(i + 3);
    }
    sum += (s1 + s2) + s3;
  }
  for (; i < end; ++i) sum += value(i);
  return sum;
}

#ifdef ANCHORMAP_AVX2_DISPATCH
// The cells of eight query points on a level of `width` x `height` shifted by (x0, y0): their
// row-major indices and which of them lie on the level (the float and the byte sums' gathers).
class CellsOfEightAvx2 {
 public:
  __attribute__((target("avx2"), always_inline))
  CellsOfEightAvx2(int x0, int y0, int width, int height)
      : shift_x_(_mm256_set1_epi32(x0)),
        shift_y_(_mm256_set1_epi32(y0)),
        width_(_mm256_set1_epi32(width)),
        sign_(_mm256_set1_epi32(static_cast<int>(0x80000000u))),
        width_flipped_(_mm256_xor_si256(width_, sign_)),
        height_flipped_(_mm256_xor_si256(_mm256_set1_epi32(height), sign_)) {}

  // Points i .. i + 7: their cells' indices, and (with `inside`) the mask of those on the level.
  __attribute__((target("avx2"), always_inline)) __m256i Index(const int32_t* xs, const int32_t* ys,
                                                               size_t i, __m256i* inside) const {
    const __m256i x =
        _mm256_add_epi32(_mm256_loadu_si256(reinterpret_cast<const __m256i*>(xs + i)), shift_x_);
    const __m256i y =
        _mm256_add_epi32(_mm256_loadu_si256(reinterpret_cast<const __m256i*>(ys + i)), shift_y_);
    if (inside != nullptr) {
      // Unsigned "x < width" as a signed compare of both sides with the sign bit flipped.
      const __m256i in_x = _mm256_cmpgt_epi32(width_flipped_, _mm256_xor_si256(x, sign_));
      const __m256i in_y = _mm256_cmpgt_epi32(height_flipped_, _mm256_xor_si256(y, sign_));
      *inside = _mm256_and_si256(in_x, in_y);
    }
    return _mm256_add_epi32(_mm256_mullo_epi32(y, width_), x);
  }

 private:
  __m256i shift_x_, shift_y_, width_, sign_, width_flipped_, height_flipped_;
};

// SumCells for exact sums, eight points at a time by AVX2 gathers (the order of the additions
// does not matter there: every partial sum is exact). Cells outside the level read nothing
// and add 0.
template <bool Inside>
__attribute__((target("avx2"), always_inline)) inline double SumCellsAvx2(
    const MaxGridPyramid::LevelView& l, const int32_t* xs, const int32_t* ys, size_t begin,
    size_t end, int x0, int y0, double sum) {
  const CellsOfEightAvx2 cells(x0, y0, l.width, l.height);
  __m256d low = _mm256_setzero_pd();
  __m256d high = _mm256_setzero_pd();
  size_t i = begin;
  for (; i + 8 <= end; i += 8) {
    __m256 v;
    if (Inside) {
      v = _mm256_i32gather_ps(l.values, cells.Index(xs, ys, i, nullptr), 4);
    } else {
      __m256i inside;
      const __m256i index = cells.Index(xs, ys, i, &inside);
      v = _mm256_mask_i32gather_ps(_mm256_setzero_ps(), l.values, index,
                                   _mm256_castsi256_ps(inside), 4);
    }
    low = _mm256_add_pd(low, _mm256_cvtps_pd(_mm256_castps256_ps128(v)));
    high = _mm256_add_pd(high, _mm256_cvtps_pd(_mm256_extractf128_ps(v, 1)));
  }
  alignas(32) double lanes[4];
  _mm256_store_pd(lanes, _mm256_add_pd(low, high));
  sum += (lanes[0] + lanes[1]) + (lanes[2] + lanes[3]);
  // The last points (fewer than eight), one at a time.
  return SumCells<Inside, /*Exact=*/false>(l, xs, ys, i, end, x0, y0, sum);
}
#endif

// The points' sums are taken in chunks; after each, whether the rest can still lift the mean
// above `floor`. The rest is bounded by the most one point adds, or, given the node's parent in
// the branch and bound (`parent_sums`: its running sums at the chunk ends), by the parent's sum
// over the same points: a parent's block of translations holds its children's, so its max-grid
// value at every point is at least theirs. `sums` (optional) receives this node's running sums,
// for its children. A margin far above the sums' rounding keeps the stop exact: a mean above
// the floor is always finished.
struct ChunkStop {
  double count;           // the mean's divisor: the points, in the sums' units
  double stop;            // the running sum plus the rest below this: stop
  double rest_per_point;  // the most one point adds, in the sums' units
};

// Sums of float values of at most max_value.
ChunkStop FloatStop(size_t n, double floor, double max_value) {
  const double count = static_cast<double>(n);
  return {count, floor * count - 1e-9 * count * std::max(1.0, max_value), max_value};
}

// Sums of ByteMaxGrids' bytes (whole 1/kScale units, exact in any order) of at most max_value;
// the mean in the floats' units, sum / (kScale n): at least the float level's mean, since every
// byte is.
ChunkStop ByteStop(size_t n, double floor, int max_value) {
  const double count = static_cast<double>(n) * ByteMaxGrids::kScale;
  return {count, floor * count - 1e-9 * count, static_cast<double>(max_value)};
}

// The one chunked loop of the four ways to sum (floats or bytes, portable or AVX2):
// `sum_chunk(begin, end, sum)` is `sum` plus the values of points [begin, end). The AVX2 callers
// are `flatten`ed, so that their target's chunk sums are inlined into this loop.
template <typename SumChunk>
inline double ChunkedMean(size_t n, const ChunkStop& stop, double floor, const double* parent_sums,
                          double* sums, const SumChunk& sum_chunk) {
  const size_t chunks = (n + kChunk - 1) / kChunk;
  double sum = 0.0;
  for (size_t chunk = 0; chunk < chunks; ++chunk) {
    const size_t begin = chunk * kChunk;
    const size_t end = std::min(n, begin + kChunk);
    sum = sum_chunk(begin, end, sum);
    if (sums != nullptr) sums[chunk] = sum;
    if (end == n) break;
    const double rest = parent_sums != nullptr ? parent_sums[chunks - 1] - parent_sums[chunk]
                                               : static_cast<double>(n - end) * stop.rest_per_point;
    const double most = sum + rest;
    if (most < stop.stop) return std::min(floor, most / stop.count);
  }
  return sum / stop.count;
}

#ifdef ANCHORMAP_AVX2_DISPATCH
// A chunk's exact float sum by AVX2 gathers (SumCellsAvx2).
template <bool Inside>
struct FloatChunkAvx2 {
  const MaxGridPyramid::LevelView& l;
  const int32_t* xs;
  const int32_t* ys;
  int x0;
  int y0;
  __attribute__((target("avx2"))) double operator()(size_t begin, size_t end, double sum) const {
    return SumCellsAvx2<Inside>(l, xs, ys, begin, end, x0, y0, sum);
  }
};

// MeanAbove for exact sums on AVX2, the chunks' sums inlined into the loop (a call and the
// sums' set-up per chunk of 32 points were a sixth of the lattice search's time): the same
// stops on the same running sums (exact: any order gives the same bits).
template <bool Inside>
__attribute__((target("avx2"), flatten)) double MeanAboveAvx2(
    const MaxGridPyramid::LevelView& l, const DiscretisedQuery& query, int k, int x0, int y0,
    double floor, double max_value, const double* parent_sums, double* sums) {
  const size_t n = query.num_points();
  return ChunkedMean(n, FloatStop(n, floor, max_value), floor, parent_sums, sums,
                     FloatChunkAvx2<Inside>{l, query.xs(k), query.ys(k), x0, y0});
}
#endif

template <bool Inside, bool Exact>
double MeanAbove(const MaxGridPyramid::LevelView& l, const DiscretisedQuery& query, int k, int x0,
                 int y0, double floor, double max_value, const double* parent_sums, double* sums) {
#ifdef ANCHORMAP_AVX2_DISPATCH
  if (Exact && CpuHasAvx2()) {
    return MeanAboveAvx2<Inside>(l, query, k, x0, y0, floor, max_value, parent_sums, sums);
  }
#endif
  const size_t n = query.num_points();
  const int32_t* xs = query.xs(k);
  const int32_t* ys = query.ys(k);
  return ChunkedMean(n, FloatStop(n, floor, max_value), floor, parent_sums, sums,
                     [&](size_t begin, size_t end, double sum) {
                       return SumCells<Inside, Exact>(l, xs, ys, begin, end, x0, y0, sum);
                     });
}

size_t NumChunks(const DiscretisedQuery& query) {
  return (query.num_points() + kChunk - 1) / kChunk;
}

// ScoreWithParent on a level given by its view (one of the pyramid's, or one built above them
// from its top: a level of the same grids' block maxima, so the same max_value and exact_sums).
double ScoreOnView(const MaxGridPyramid& grids, const MaxGridPyramid::LevelView& l,
                   const DiscretisedQuery& query, int k, int dx, int dy, double floor,
                   const double* parent_sums, double* sums) {
  if (query.num_points() == 0) return 0.0;
  const int x0 = dx + l.offset;
  const int y0 = dy + l.offset;
  const DiscretisedQuery::Box& box = query.box(k);
  const bool inside = box.min.x() + x0 >= 0 && box.min.y() + y0 >= 0 &&
                      box.max.x() + x0 < l.width && box.max.y() + y0 < l.height;
  const double max_value = grids.max_value();
  // Below 2^22 points a sum of values <= 1 stays below 2^22 (exact_sums' condition).
  if (grids.exact_sums() && query.num_points() < (size_t{1} << 22)) {
    return inside
               ? MeanAbove<true, true>(l, query, k, x0, y0, floor, max_value, parent_sums, sums)
               : MeanAbove<false, true>(l, query, k, x0, y0, floor, max_value, parent_sums, sums);
  }
  return inside ? MeanAbove<true, false>(l, query, k, x0, y0, floor, max_value, parent_sums, sums)
                : MeanAbove<false, false>(l, query, k, x0, y0, floor, max_value, parent_sums, sums);
}

double ScoreWithParent(const MaxGridPyramid& grids, int level, const DiscretisedQuery& query, int k,
                       int dx, int dy, double floor, const double* parent_sums, double* sums) {
  return ScoreOnView(grids, grids.level(level), query, k, dx, dy, floor, parent_sums, sums);
}

// Branch and bound's inner nodes on ByteMaxGrids: MeanAbove's stops on integer sums (exact in
// any order, so the AVX2 path and the portable one stop alike). `parent_sums` and `sums` count
// bytes.
template <bool Inside>
int64_t SumBytes(const ByteMaxGrids::LevelView& l, const int32_t* xs, const int32_t* ys,
                 size_t begin, size_t end, int x0, int y0) {
  int64_t sum = 0;
  for (size_t i = begin; i < end; ++i) {
    const int x = xs[i] + x0;
    const int y = ys[i] + y0;
    if (!Inside && (static_cast<unsigned>(x) >= static_cast<unsigned>(l.width) ||
                    static_cast<unsigned>(y) >= static_cast<unsigned>(l.height))) {
      continue;
    }
    sum += l.values[static_cast<size_t>(y) * static_cast<size_t>(l.width) + static_cast<size_t>(x)];
  }
  return sum;
}

template <bool Inside>
double ByteMeanAbove(const ByteMaxGrids::LevelView& l, const DiscretisedQuery& query, int k, int x0,
                     int y0, double floor, int max_value, const double* parent_sums, double* sums) {
  const size_t n = query.num_points();
  const int32_t* xs = query.xs(k);
  const int32_t* ys = query.ys(k);
  // Whole numbers below 2^53: the double running sum is the integer one.
  return ChunkedMean(n, ByteStop(n, floor, max_value), floor, parent_sums, sums,
                     [&](size_t begin, size_t end, double sum) {
                       return sum +
                              static_cast<double>(SumBytes<Inside>(l, xs, ys, begin, end, x0, y0));
                     });
}

#ifdef ANCHORMAP_AVX2_DISPATCH
// A chunk's byte sum with eight points per gather: four bytes read at each cell (ByteMaxGrids
// keeps three readable bytes past the last), the low one kept; a chunk's 64 points add at most
// 8 x 255 per 32-bit lane.
template <bool Inside>
struct ByteChunkAvx2 {
  const ByteMaxGrids::LevelView& l;
  const int32_t* xs;
  const int32_t* ys;
  int x0;
  int y0;
  CellsOfEightAvx2 cells;
  __attribute__((target("avx2"))) double operator()(size_t begin, size_t end, double sum) const {
    const int* base = reinterpret_cast<const int*>(l.values);
    const __m256i low_byte = _mm256_set1_epi32(0xFF);
    __m256i lanes = _mm256_setzero_si256();
    size_t i = begin;
    for (; i + 8 <= end; i += 8) {
      __m256i v;
      if (Inside) {
        v = _mm256_i32gather_epi32(base, cells.Index(xs, ys, i, nullptr), 1);
      } else {
        __m256i inside;
        const __m256i index = cells.Index(xs, ys, i, &inside);
        v = _mm256_mask_i32gather_epi32(_mm256_setzero_si256(), base, index, inside, 1);
      }
      lanes = _mm256_add_epi32(lanes, _mm256_and_si256(v, low_byte));
    }
    const __m128i pairs =
        _mm_add_epi32(_mm256_castsi256_si128(lanes), _mm256_extracti128_si256(lanes, 1));
    const __m128i quads = _mm_add_epi32(pairs, _mm_shuffle_epi32(pairs, _MM_SHUFFLE(1, 0, 3, 2)));
    const __m128i total = _mm_add_epi32(quads, _mm_shuffle_epi32(quads, _MM_SHUFFLE(2, 3, 0, 1)));
    // The last points (fewer than eight) one at a time.
    const int64_t chunk = _mm_cvtsi128_si32(total) + SumBytes<Inside>(l, xs, ys, i, end, x0, y0);
    return sum + static_cast<double>(chunk);
  }
};

// ByteMeanAbove with ByteChunkAvx2's sums inlined into the loop.
template <bool Inside>
__attribute__((target("avx2"), flatten)) double ByteMeanAboveAvx2(
    const ByteMaxGrids::LevelView& l, const DiscretisedQuery& query, int k, int x0, int y0,
    double floor, int max_value, const double* parent_sums, double* sums) {
  const size_t n = query.num_points();
  const ByteChunkAvx2<Inside> sum_chunk{
      l, query.xs(k), query.ys(k), x0, y0, CellsOfEightAvx2(x0, y0, l.width, l.height)};
  return ChunkedMean(n, ByteStop(n, floor, max_value), floor, parent_sums, sums, sum_chunk);
}
#endif

double ByteScore(const ByteMaxGrids& bytes, int level, const DiscretisedQuery& query, int k, int dx,
                 int dy, double floor, const double* parent_sums, double* sums) {
  if (query.num_points() == 0) return 0.0;
  const ByteMaxGrids::LevelView l = bytes.level(level);
  const int x0 = dx + l.offset;
  const int y0 = dy + l.offset;
  const DiscretisedQuery::Box& box = query.box(k);
  const bool inside = box.min.x() + x0 >= 0 && box.min.y() + y0 >= 0 &&
                      box.max.x() + x0 < l.width && box.max.y() + y0 < l.height;
  const int max_value = bytes.max_value();
#ifdef ANCHORMAP_AVX2_DISPATCH
  if (CpuHasAvx2()) {
    return inside
               ? ByteMeanAboveAvx2<true>(l, query, k, x0, y0, floor, max_value, parent_sums, sums)
               : ByteMeanAboveAvx2<false>(l, query, k, x0, y0, floor, max_value, parent_sums, sums);
  }
#endif
  return inside ? ByteMeanAbove<true>(l, query, k, x0, y0, floor, max_value, parent_sums, sums)
                : ByteMeanAbove<false>(l, query, k, x0, y0, floor, max_value, parent_sums, sums);
}

}  // namespace

double ScoreOnLevelAbove(const MaxGridPyramid& grids, int level, const DiscretisedQuery& query,
                         int k, int dx, int dy, double floor) {
  return ScoreWithParent(grids, level, query, k, dx, dy, floor, nullptr, nullptr);
}

std::optional<LatticePose> ExhaustiveSearch(const MaxGridPyramid& grids,
                                            const DiscretisedQuery& query,
                                            const SearchWindow& window, double min_score,
                                            LatticeSearchStats* stats) {
  std::optional<LatticePose> best;
  double best_score = min_score;
  for (int k = -window.half_angles; k <= window.half_angles; ++k) {
    for (int dy = -window.half_cells_y; dy <= window.half_cells_y; ++dy) {
      for (int dx = -window.half_cells_x; dx <= window.half_cells_x; ++dx) {
        const double score = ScoreOnLevel(grids, 0, query, k, dx, dy);
        if (stats != nullptr) {
          ++stats->scored_nodes;
          ++stats->leaves;
        }
        if (score > best_score) {
          best_score = score;
          best = LatticePose{k, dx, dy, score};
        }
      }
    }
  }
  return best;
}

namespace {

#ifdef ANCHORMAP_AVX2_DISPATCH
// MaxCellMove eight cells at a time (the maximum of whole numbers: any order, the same).
__attribute__((target("avx2"))) int MaxCellMoveAvx2(const int32_t* a, const int32_t* b, size_t n) {
  __m256i most = _mm256_setzero_si256();
  size_t i = 0;
  for (; i + 8 <= n; i += 8) {
    const __m256i va = _mm256_loadu_si256(reinterpret_cast<const __m256i*>(a + i));
    const __m256i vb = _mm256_loadu_si256(reinterpret_cast<const __m256i*>(b + i));
    most = _mm256_max_epi32(most, _mm256_abs_epi32(_mm256_sub_epi32(va, vb)));
  }
  alignas(32) int32_t lanes[8];
  _mm256_store_si256(reinterpret_cast<__m256i*>(lanes), most);
  int result = 0;
  for (const int32_t lane : lanes) result = std::max(result, lane);
  for (; i < n; ++i) result = std::max(result, std::abs(a[i] - b[i]));
  return result;
}
#endif

// Heading groups are split down to blocks of 2^kSingleHeadingBlock cells; there each heading of
// a group goes on alone (measured on FR079's global searches: 3 gave the fewest point sums, 2 and
// 4 about a sixth more).
constexpr int kSingleHeadingBlock = 3;

// Headings [k, k + 2^g) (cut at the window; g = 0: heading k alone) and translations
// [dx, dx + 2^b) x [dy, dy + 2^b) (cut at the window).
struct Node {
  int k;
  int g;
  int b;
  int dx;
  int dy;
  double bound;
  int slot;        // where its running sums are kept (see Descend)
  bool dominates;  // its running sums bound its single-heading children's, point by point
};

// (k, dy, dx) order: ExhaustiveSearch's, which decides between equal scores.
bool Precedes(int k, int dx, int dy, const LatticePose& other) {
  if (k != other.k) return k < other.k;
  if (dy != other.dy) return dy < other.dy;
  return dx < other.dx;
}

class BranchAndBoundSearch {
 public:
  BranchAndBoundSearch(const MaxGridPyramid& grids, const DiscretisedQuery& query,
                       const SearchWindow& window, double min_score, LatticeSearchStats* stats,
                       const ByteMaxGrids* bytes, bool lazy_roots)
      : lazy_roots_(lazy_roots),
        grids_(grids),
        // Bytes for the inner nodes only where the leaves' sums are exact: then a node's mean
        // on the bytes is at least every leaf's score as the floats give it, bit for bit.
        bytes_(bytes != nullptr && ByteBoundsApply(grids, query) ? bytes : nullptr),
        query_(query),
        window_(window),
        best_score_(min_score),
        stats_(stats),
        chunks_(NumChunks(query)) {
    if (bytes_ == nullptr && !grids.levels_built()) {
      throw std::logic_error("BranchAndBound: float bounds need the pyramid's levels built");
    }
  }

  std::optional<LatticePose> Run() {
    const int top = grids_.num_levels() - 1;
    // Grouped roots one level below the top: a group of 2^b headings turns the query's farthest
    // point by about 2^b cells (the angle step moves it by one), so its bound fits on level b + 1.
    const int root_b = top - 1 > kSingleHeadingBlock ? top - 1 : top;
    const int root_g = root_b == top ? 0 : root_b;
    deviations_.resize(static_cast<size_t>(root_g) + 1);
    // Depth first: the nodes being descended at each depth, and their running sums.
    const size_t depths = static_cast<size_t>(top + root_g + 2);
    nodes_.resize(depths);
    sums_.resize(depths);
    std::vector<Node>& roots = nodes_[0];
    roots.clear();
    const int step = 1 << root_b;
    for (int k = -window_.half_angles; k <= window_.half_angles; k += 1 << root_g) {
      for (int dy = -window_.half_cells_y; dy <= window_.half_cells_y; dy += step) {
        for (int dx = -window_.half_cells_x; dx <= window_.half_cells_x; dx += step) {
          roots.push_back(Group(k, root_g, root_b, dx, dy));
        }
      }
    }
    if (lazy_roots_ && bytes_ == nullptr && root_g == 0 && top >= 2 &&
        roots.size() > kMinLazyRoots) {
      DescendLazyRoots(top);
      return best_;
    }
    BoundAll(0, nullptr);
    Descend(0);
    return best_;
  }

  // The window's centre as the best leaf so far when it scores above the bar: any better leaf,
  // or an equal one earlier in (k, dy, dx) order, still replaces it (Descend).
  void ScoreCentreFirst() {
    const double centre = Score(0, 0, 0, 0, nullptr, nullptr);
    if (centre > best_score_) {
      best_score_ = centre;
      best_ = LatticePose{0, 0, 0, centre};
    }
  }

 private:
  int LastHeading(int k, int g) const { return std::min(k + (1 << g) - 1, window_.half_angles); }

  // A group's node, or a single heading's when the window leaves the group one.
  Node Group(int k, int g, int b, int dx, int dy) const {
    if (g > 0 && LastHeading(k, g) == k) g = 0;
    return Node{k, g, b, dx, dy, 0.0, 0, false};
  }

  double* Sums(int depth, int slot) {
    return sums_[depth].data() + static_cast<size_t>(slot) * chunks_;
  }

  struct Deviation {
    int centre = 0;  // the heading the group is scored at
    int x = -1;      // the most any point's cell moves along x from its cell at the centre
    int y = -1;
  };

  // The group's centre heading and how far its other headings move the query's cells (memoised:
  // children of one group share it).
  const Deviation& GroupDeviation(int k, int g) {
    std::vector<Deviation>& memo = deviations_[static_cast<size_t>(g)];
    const size_t index = static_cast<size_t>((k + window_.half_angles) >> g);
    if (memo.size() <= index) memo.resize(index + 1);
    Deviation& d = memo[index];
    if (d.x >= 0) return d;
    const int last = LastHeading(k, g);
    d.centre = std::min(k + (1 << (g - 1)), last);
    d.x = 0;
    d.y = 0;
    const size_t n = query_.num_points();
    for (int h = k; h <= last; ++h) {
      d.x = std::max(d.x, MaxCellMove(query_.xs(h), query_.xs(d.centre), n));
      d.y = std::max(d.y, MaxCellMove(query_.ys(h), query_.ys(d.centre), n));
    }
    return d;
  }

  // Bounds the nodes at `depth`: the roots, or the children of one node (`parent_sums`: its
  // running sums when it dominates its single-heading children, else null).
  void BoundAll(int depth, const double* parent_sums) {
    std::vector<Node>& nodes = nodes_[depth];
    std::vector<double>& sums = sums_[depth];
    if (sums.size() < nodes.size() * chunks_) sums.resize(nodes.size() * chunks_);
    for (size_t i = 0; i < nodes.size(); ++i) {
      Node& node = nodes[i];
      node.slot = static_cast<int>(i);
      // Leaves need no sums (nothing descends from them).
      double* own = node.g == 0 && node.b == 0 ? nullptr : Sums(depth, node.slot);
      Bound(&node, node.g == 0 ? parent_sums : nullptr, own);
    }
  }

  // A single heading's bound is its score on level b. A group's: every point, at any heading of
  // the group, lies within (x, y) cells of where it lies at the centre, so over the node's
  // translations it lands in a block of 2^b + 2 max(x, y) cells around its centre cell shifted
  // by the node's corner, whose maximum is the value of the level just as wide, read at the
  // corner minus (x, y). That level's block also holds every single heading's block of the same
  // translations: the group's sums bound theirs point by point.
  void Bound(Node* node, const double* parent_sums, double* sums) {
    if (node->g == 0) {
      node->bound = Score(node->b, node->k, node->dx, node->dy, parent_sums, sums);
      node->dominates = true;
      return;
    }
    const Deviation& d = GroupDeviation(node->k, node->g);
    const int span = (1 << node->b) + 2 * std::max(d.x, d.y);
    int level = node->b;
    while ((1 << level) < span) ++level;
    if (level >= grids_.num_levels()) {
      // No level is wide enough: always descended.
      node->bound = std::numeric_limits<double>::infinity();
      node->dominates = false;
      return;
    }
    node->bound = Score(level, d.centre, node->dx - d.x, node->dy - d.y, nullptr, sums);
    node->dominates = true;
  }

  double Score(int level, int k, int dx, int dy, const double* parent_sums, double* sums) {
    if (stats_ != nullptr) {
      ++stats_->scored_nodes;
      if (level == 0) ++stats_->leaves;
    }
    // Only whether a node can reach the best leaf so far matters: its score is finished only
    // when it does.
    if (bytes_ == nullptr) {
      return ScoreWithParent(grids_, level, query_, k, dx, dy, best_score_, parent_sums, sums);
    }
    if (level > 0) {
      return ByteScore(*bytes_, level, query_, k, dx, dy, best_score_, parent_sums, sums);
    }
    // A leaf below a node scored on the bytes: its sums in the floats' units.
    if (parent_sums != nullptr) {
      scaled_parent_sums_.resize(chunks_);
      for (size_t c = 0; c < chunks_; ++c) {
        scaled_parent_sums_[c] = parent_sums[c] / ByteMaxGrids::kScale;
      }
      parent_sums = scaled_parent_sums_.data();
    }
    return ScoreWithParent(grids_, level, query_, k, dx, dy, best_score_, parent_sums, sums);
  }

  // A node is descended when it may hold a leaf above the best so far, or one equal to it that
  // comes first in (k, dy, dx) order (an equal bound: ties are decided as ExhaustiveSearch
  // decides them, whatever the order of the descent).
  bool Promising(double bound) const {
    return bound > best_score_ || (best_.has_value() && bound == best_score_);
  }

  void Descend(int depth) {
    std::vector<Node>& nodes = nodes_[depth];
    BestFirst order(&nodes);
    for (std::optional<Node> next = order.Next(); next; next = order.Next()) {
      const Node node = *next;
      if (!Promising(node.bound)) break;  // best first: no later node can do better
      Visit(depth, node);
    }
  }

  // A promising node at `depth`: a leaf is a candidate best pose; an inner node's children are
  // bounded and descended.
  void Visit(int depth, const Node& node) {
    if (node.g == 0 && node.b == 0) {
      if (node.bound > best_score_ || Precedes(node.k, node.dx, node.dy, *best_)) {
        best_score_ = node.bound;
        best_ = LatticePose{node.k, node.dx, node.dy, node.bound};
      }
      return;
    }
    std::vector<Node>& children = nodes_[depth + 1];
    children.clear();
    if (node.g > 0 && node.b <= kSingleHeadingBlock) {
      // Each heading alone, the same translations.
      for (int k = node.k; k <= LastHeading(node.k, node.g); ++k) {
        children.push_back(Node{k, 0, node.b, node.dx, node.dy, 0.0, 0, false});
      }
    } else {
      ForEachHalfTimesQuarter(node, [&children](const Node& child) { children.push_back(child); });
    }
    // Single headings below a node that dominates them stop early on its sums; a group's
    // bound is read elsewhere than its parent's and cannot.
    const double* parent_sums = node.dominates ? Sums(depth, node.slot) : nullptr;
    BoundAll(depth + 1, parent_sums);
    Descend(depth + 1);
  }

  // The roots (single headings on the top level: a pyramid too shallow for heading groups,
  // such as the loop closures' wide searches') bounded only when a group of them may still
  // hold a leaf above the best so far. Groups of 2^g headings and 2^B x 2^B translations above
  // the roots are bounded as heading groups are (Bound), on levels built above the pyramid's
  // top for this search, and visited best first together with the roots bounded so far. A root
  // is bounded as the eager descent bounds it, on the best score so far: a root that can beat
  // it (or equal it) gets its full score and sums, as in the eager descent; one that cannot
  // never will (the best only rises), whatever value its early stop leaves. A group goes
  // before a root of an equal bound, so a root comes out only after every root above it (or
  // equal and earlier): the roots are visited in the eager descent's order with the same bounds
  // and sums, and the descent stops where it stops, at the first bound that cannot beat the
  // best. The same best pose, the same nodes below the
  // roots; stats count every root, as the eager descent scores them all (the loop closures'
  // budget charges wide searches by their nodes). On 100 x 180, 98 % of the wide searches'
  // nodes were roots, nearly all never descended.
  void DescendLazyRoots(int top) {
    const std::vector<Node>& roots = nodes_[0];
    if (stats_ != nullptr) stats_->scored_nodes += static_cast<int64_t>(roots.size());
    // Run's order of the roots: heading, then dy, then dx, in steps of 2^top.
    const size_t per_row = static_cast<size_t>((2 * window_.half_cells_x >> top) + 1);
    const size_t per_heading = per_row * static_cast<size_t>((2 * window_.half_cells_y >> top) + 1);
    if (sums_[0].size() < roots.size() * chunks_) sums_[0].resize(roots.size() * chunks_);
    BuildLevelsAboveTop(top);
    // The top groups: as many headings as blocks of 2^(top + 1) cells are wide (a group's
    // deviation, about half its headings, then fits the level above).
    const int top_g = top + 1;
    const int top_b = top + 1;
    deviations_.resize(static_cast<size_t>(top_g) + 1);
    std::vector<Lazy> queue;
    std::vector<Node> groups;
    auto push_group = [&](Node group) {
      group.bound = LazyGroupBound(group, top);
      group.slot = static_cast<int>(groups.size());
      groups.push_back(group);
      queue.push_back(Lazy{group.bound, true, group.slot});
      std::push_heap(queue.begin(), queue.end(), Lazy::Later);
    };
    auto push_root = [&](int k, int dx, int dy) {
      const size_t slot = static_cast<size_t>(k + window_.half_angles) * per_heading +
                          static_cast<size_t>((dy + window_.half_cells_y) >> top) * per_row +
                          static_cast<size_t>((dx + window_.half_cells_x) >> top);
      Node& root = nodes_[0][slot];
      root.slot = static_cast<int>(slot);
      root.bound = ScoreRoot(top, root, Sums(0, root.slot));
      root.dominates = true;
      queue.push_back(Lazy{root.bound, false, root.slot});
      std::push_heap(queue.begin(), queue.end(), Lazy::Later);
    };
    const int top_step = 1 << top_b;
    for (int k = -window_.half_angles; k <= window_.half_angles; k += 1 << top_g) {
      for (int dy = -window_.half_cells_y; dy <= window_.half_cells_y; dy += top_step) {
        for (int dx = -window_.half_cells_x; dx <= window_.half_cells_x; dx += top_step) {
          push_group(Group(k, top_g, top_b, dx, dy));
        }
      }
    }
    while (!queue.empty()) {
      std::pop_heap(queue.begin(), queue.end(), Lazy::Later);
      const Lazy next = queue.back();
      queue.pop_back();
      if (!Promising(next.bound)) break;  // best first: nothing left can do better
      if (!next.group) {
        Visit(0, nodes_[0][static_cast<size_t>(next.slot)]);
        continue;
      }
      const Node group = groups[static_cast<size_t>(next.slot)];
      if (group.b == top) {
        // Each heading alone: the roots.
        for (int k = group.k; k <= LastHeading(group.k, group.g); ++k) {
          push_root(k, group.dx, group.dy);
        }
        continue;
      }
      ForEachHalfTimesQuarter(group, push_group);
    }
  }

  // The children of a node that splits both ways: halves of its group (none for a single
  // heading) times quarters of its block, cut at the window, in (k, dy, dx) order.
  template <typename Use>
  void ForEachHalfTimesQuarter(const Node& node, const Use& use) const {
    const int half = 1 << (node.b - 1);
    const int group_step = node.g > 0 ? 1 << (node.g - 1) : 1;
    for (int k = node.k; k <= LastHeading(node.k, node.g); k += group_step) {
      for (int oy = 0; oy <= half; oy += half) {
        for (int ox = 0; ox <= half; ox += half) {
          const int dx = node.dx + ox;
          const int dy = node.dy + oy;
          if (dx > window_.half_cells_x || dy > window_.half_cells_y) continue;
          use(Group(k, std::max(node.g - 1, 0), node.b - 1, dx, dy));
        }
      }
    }
  }

  // A root's bound as BoundAll gives it (its score on the top level), not counted in the stats
  // (DescendLazyRoots counts every root).
  double ScoreRoot(int top, const Node& root, double* sums) {
    return ScoreWithParent(grids_, top, query_, root.k, root.dx, root.dy, best_score_, nullptr,
                           sums);
  }

  // A lazy group's bound (Bound's for a heading group; a single heading's score on level b),
  // on the pyramid's levels or those built above it; infinite when none is wide enough.
  double LazyGroupBound(const Node& group, int top) {
    Deviation d;
    d.centre = group.k;
    d.x = d.y = 0;
    if (group.g > 0) d = GroupDeviation(group.k, group.g);
    const int span = (1 << group.b) + 2 * std::max(d.x, d.y);
    int level = group.b;
    while ((1 << level) < span) ++level;
    if (level > top + kLevelsAboveTop) return std::numeric_limits<double>::infinity();
    const MaxGridPyramid::LevelView view =
        level <= top ? grids_.level(level) : above_top_[static_cast<size_t>(level - top - 1)].view;
    return ScoreOnView(grids_, view, query_, d.centre, group.dx - d.x, group.dy - d.y, best_score_,
                       nullptr, nullptr);
  }

  // Levels top + 1 .. top + kLevelsAboveTop of the pyramid, by its own recursion.
  void BuildLevelsAboveTop(int top) {
    above_top_.resize(kLevelsAboveTop);
    MaxGridPyramid::LevelView below = grids_.level(top);
    for (int i = 0; i < kLevelsAboveTop; ++i) {
      const int h = top + 1 + i;
      const int half = 1 << (h - 1);
      AboveTop& level = above_top_[static_cast<size_t>(i)];
      const size_t cells =
          static_cast<size_t>(below.width + half) * static_cast<size_t>(below.height + half);
      level.values.reset(new float[cells]);
      BuildMaxLevel(below.values, below.width, below.height, half, level.values.get());
      level.view = {(1 << h) - 1, below.width + half, below.height + half, level.values.get()};
      below = level.view;
    }
  }

  // A lazy root or group in DescendLazyRoots' queue.
  struct Lazy {
    double bound;
    bool group;
    int slot;  // the root's, or the group's index
    // Whether a comes after b: a lower bound; at an equal bound, a root after a group, and
    // roots (groups) in their slots' order.
    static bool Later(const Lazy& a, const Lazy& b) {
      if (a.bound != b.bound) return a.bound < b.bound;
      if (a.group != b.group) return !a.group;
      return a.slot > b.slot;
    }
  };

  struct AboveTop {
    std::unique_ptr<float[]> values;
    MaxGridPyramid::LevelView view;
  };

  // The nodes of one depth, best bound first, equal bounds in their given order (their slot:
  // BoundAll numbers them so). Many nodes (the roots: every translation block and heading
  // group of the window) go into a heap and come out one at a time, since the descent
  // usually stops long before the last: sorting them all was a third of a wide loop search's
  // time once the windows reached their cap. A few (a node's children) are insertion-sorted,
  // without a heap's or std::stable_sort's overhead.
  class BestFirst {
   public:
    explicit BestFirst(std::vector<Node>* nodes) : nodes_(*nodes), left_(nodes->size()) {
      heap_ = left_ > 16;
      if (heap_) {
        std::make_heap(nodes_.begin(), nodes_.end(), Later);
        return;
      }
      for (size_t i = 1; i < left_; ++i) {
        const Node node = nodes_[i];
        size_t j = i;
        for (; j > 0 && node.bound > nodes_[j - 1].bound; --j) nodes_[j] = nodes_[j - 1];
        nodes_[j] = node;
      }
    }
    std::optional<Node> Next() {
      if (left_ == 0) return std::nullopt;
      if (!heap_) return nodes_[nodes_.size() - left_--];
      std::pop_heap(nodes_.begin(), nodes_.begin() + static_cast<std::ptrdiff_t>(left_), Later);
      return nodes_[--left_];
    }

   private:
    // Whether a comes after b: a lower bound, or an equal one given later.
    static bool Later(const Node& a, const Node& b) {
      return a.bound < b.bound || (a.bound == b.bound && a.slot > b.slot);
    }
    std::vector<Node>& nodes_;
    size_t left_;
    bool heap_ = false;
  };

  // Lazy roots only above this many (a local window's few roots are bounded at once).
  static constexpr size_t kMinLazyRoots = 64;
  // Levels built above the pyramid's top for the lazy roots' groups.
  static constexpr int kLevelsAboveTop = 2;

  bool lazy_roots_;
  const MaxGridPyramid& grids_;
  const ByteMaxGrids* bytes_;  // null: every level on the floats
  const DiscretisedQuery& query_;
  const SearchWindow& window_;
  double best_score_;
  LatticeSearchStats* stats_;
  std::optional<LatticePose> best_;
  size_t chunks_;
  std::vector<std::vector<Node>> nodes_;
  std::vector<std::vector<double>> sums_;
  std::vector<std::vector<Deviation>> deviations_;  // per group size (log2), per group
  std::vector<double> scaled_parent_sums_;
  std::vector<AboveTop> above_top_;
};

}  // namespace

bool ByteBoundsApply(const MaxGridPyramid& grids, const DiscretisedQuery& query) {
  // Below 2^22 points a sum of values <= 1 stays below 2^22 (exact_sums' condition).
  return grids.exact_sums() && query.num_points() < (size_t{1} << 22);
}

int MaxCellMove(const int32_t* a, const int32_t* b, size_t n) {
#ifdef ANCHORMAP_AVX2_DISPATCH
  if (CpuHasAvx2()) return MaxCellMoveAvx2(a, b, n);
#endif
  int most = 0;
  for (size_t i = 0; i < n; ++i) most = std::max(most, std::abs(a[i] - b[i]));
  return most;
}

std::optional<LatticePose> BranchAndBound(const MaxGridPyramid& grids,
                                          const DiscretisedQuery& query, const SearchWindow& window,
                                          double min_score, LatticeSearchStats* stats,
                                          const ByteMaxGrids* bytes, bool centre_first,
                                          bool lazy_roots) {
  BranchAndBoundSearch search(grids, query, window, min_score, stats, bytes, lazy_roots);
  if (centre_first) search.ScoreCentreFirst();
  return search.Run();
}

}  // namespace anchormap
