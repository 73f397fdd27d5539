#include "common/scan_matching/lattice_search.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>

#if defined(__x86_64__) && defined(__GNUC__)
#include <immintrin.h>
#elif defined(__SSE2__)
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

DiscretisedQuery::DiscretisedQuery(const PointCloud& query, const SearchWindow& window,
                                   const GridGeometry& geometry)
    : half_angles_(window.half_angles), num_points_(query.size()) {
  const size_t headings = static_cast<size_t>(2 * window.half_angles + 1);
  boxes_.resize(headings);
  xs_.resize(headings);
  ys_.resize(headings);
#if defined(__SSE2__)
  const __m128d origin = _mm_set_pd(geometry.origin.y(), geometry.origin.x());
  const __m128d resolution = _mm_set1_pd(geometry.resolution);
#endif
  for (int k = -window.half_angles; k <= window.half_angles; ++k) {
    const Pose2 pose(window.center.x(), window.center.y(),
                     window.center.theta() + k * window.angle_step_rad);
    const Eigen::Matrix2d R = pose.rotation();
    const Eigen::Vector2d t = pose.translation();
    std::vector<int32_t>& xs = xs_[k + half_angles_];
    std::vector<int32_t>& ys = ys_[k + half_angles_];
    xs.resize(query.size());
    ys.resize(query.size());
    Box& box = boxes_[k + half_angles_];
    box.min.setConstant(std::numeric_limits<int>::max());
    box.max.setConstant(std::numeric_limits<int>::min());
    for (size_t i = 0; i < query.size(); ++i) {
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
constexpr size_t kChunk = 32;

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

#if defined(__x86_64__) && defined(__GNUC__)
#define ANCHORMAP_HAS_AVX2_SUM 1
// SumCells for exact sums, eight points at a time by AVX2 gathers (the order of the additions
// does not matter there: every partial sum is exact). Cells outside the level read nothing
// and add 0.
template <bool Inside>
__attribute__((target("avx2"))) double SumCellsAvx2(const MaxGridPyramid::LevelView& l,
                                                    const int32_t* xs, const int32_t* ys,
                                                    size_t begin, size_t end, int x0, int y0,
                                                    double sum) {
  const __m256i shift_x = _mm256_set1_epi32(x0);
  const __m256i shift_y = _mm256_set1_epi32(y0);
  const __m256i width = _mm256_set1_epi32(l.width);
  // Unsigned "x < width" as a signed compare of both sides with the sign bit flipped.
  const __m256i sign = _mm256_set1_epi32(static_cast<int>(0x80000000u));
  const __m256i width_flipped = _mm256_xor_si256(width, sign);
  const __m256i height_flipped = _mm256_xor_si256(_mm256_set1_epi32(l.height), sign);
  __m256d low = _mm256_setzero_pd();
  __m256d high = _mm256_setzero_pd();
  size_t i = begin;
  for (; i + 8 <= end; i += 8) {
    const __m256i x =
        _mm256_add_epi32(_mm256_loadu_si256(reinterpret_cast<const __m256i*>(xs + i)), shift_x);
    const __m256i y =
        _mm256_add_epi32(_mm256_loadu_si256(reinterpret_cast<const __m256i*>(ys + i)), shift_y);
    const __m256i index = _mm256_add_epi32(_mm256_mullo_epi32(y, width), x);
    __m256 v;
    if (Inside) {
      v = _mm256_i32gather_ps(l.values, index, 4);
    } else {
      const __m256i in_x = _mm256_cmpgt_epi32(width_flipped, _mm256_xor_si256(x, sign));
      const __m256i in_y = _mm256_cmpgt_epi32(height_flipped, _mm256_xor_si256(y, sign));
      const __m256 mask = _mm256_castsi256_ps(_mm256_and_si256(in_x, in_y));
      v = _mm256_mask_i32gather_ps(_mm256_setzero_ps(), l.values, index, mask, 4);
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
bool HasAvx2() {
  static const bool has = [] {
    __builtin_cpu_init();
    return __builtin_cpu_supports("avx2") != 0;
  }();
  return has;
}
#endif

// The points' sums are taken in chunks; after each, whether the rest can still lift the mean
// above `floor`. The rest is bounded by max_value per point, or, given the node's parent in the
// branch and bound (`parent_sums`: its running sums at the chunk ends), by the parent's sum over
// the same points: a parent's block of translations holds its children's, so its max-grid value
// at every point is at least theirs. `sums` (optional) receives this node's running sums, for
// its children. A margin far above the sums' rounding keeps the stop exact: a mean above the
// floor is always finished.
template <bool Inside, bool Exact>
double MeanAbove(const MaxGridPyramid::LevelView& l, const DiscretisedQuery& query, int k, int x0,
                 int y0, double floor, double max_value, const double* parent_sums, double* sums) {
  const size_t n = query.num_points();
  const double count = static_cast<double>(n);
  const double stop = floor * count - 1e-9 * count * std::max(1.0, max_value);
  const size_t chunks = (n + kChunk - 1) / kChunk;
  double sum = 0.0;
  for (size_t chunk = 0; chunk < chunks; ++chunk) {
    const size_t begin = chunk * kChunk;
    const size_t end = std::min(n, begin + kChunk);
#ifdef ANCHORMAP_HAS_AVX2_SUM
    if (Exact && HasAvx2()) {
      sum = SumCellsAvx2<Inside>(l, query.xs(k), query.ys(k), begin, end, x0, y0, sum);
    } else {
      sum = SumCells<Inside, Exact>(l, query.xs(k), query.ys(k), begin, end, x0, y0, sum);
    }
#else
    sum = SumCells<Inside, Exact>(l, query.xs(k), query.ys(k), begin, end, x0, y0, sum);
#endif
    if (sums != nullptr) sums[chunk] = sum;
    if (end == n) break;
    const double rest = parent_sums != nullptr ? parent_sums[chunks - 1] - parent_sums[chunk]
                                               : static_cast<double>(n - end) * max_value;
    const double most = sum + rest;
    if (most < stop) return std::min(floor, most / count);
  }
  return sum / count;
}

size_t NumChunks(const DiscretisedQuery& query) {
  return (query.num_points() + kChunk - 1) / kChunk;
}

double ScoreWithParent(const MaxGridPyramid& grids, int level, const DiscretisedQuery& query, int k,
                       int dx, int dy, double floor, const double* parent_sums, double* sums) {
  if (query.num_points() == 0) return 0.0;
  const MaxGridPyramid::LevelView l = grids.level(level);
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

struct Node {
  int k;
  int dx;  // lower corner of the block of translations
  int dy;
  double bound;
  int slot;  // where its running sums are kept (see Descend)
};

class BranchAndBoundSearch {
 public:
  BranchAndBoundSearch(const MaxGridPyramid& grids, const DiscretisedQuery& query,
                       const SearchWindow& window, double min_score, LatticeSearchStats* stats)
      : grids_(grids),
        query_(query),
        window_(window),
        best_score_(min_score),
        stats_(stats),
        chunks_(NumChunks(query)) {}

  std::optional<LatticePose> Run() {
    const int top = grids_.num_levels() - 1;
    const int step = 1 << top;
    std::vector<Node> roots;
    for (int k = -window_.half_angles; k <= window_.half_angles; ++k) {
      for (int dy = -window_.half_cells_y; dy <= window_.half_cells_y; dy += step) {
        for (int dx = -window_.half_cells_x; dx <= window_.half_cells_x; dx += step) {
          roots.push_back(Node{k, dx, dy, 0.0, static_cast<int>(roots.size())});
        }
      }
    }
    // Running sums per level: the roots', then at each lower level those of the (at most 4)
    // children being descended (one set per level at a time: the descent is depth first).
    sums_.resize(grids_.num_levels());
    sums_[top].resize(roots.size() * chunks_);
    for (int level = 0; level < top; ++level) sums_[level].resize(4 * chunks_);
    for (Node& root : roots) {
      root.bound = Score(top, root.k, root.dx, root.dy, nullptr, Sums(top, root.slot));
    }
    Descend(top, roots.data(), roots.size());
    return best_;
  }

 private:
  double* Sums(int level, int slot) {
    return sums_[level].data() + static_cast<size_t>(slot) * chunks_;
  }

  double Score(int level, int k, int dx, int dy, const double* parent_sums, double* sums) {
    if (stats_ != nullptr) {
      ++stats_->scored_nodes;
      if (level == 0) ++stats_->leaves;
    }
    // Only whether a node beats the best leaf so far matters (a node at or below it is never
    // expanded): its score is finished only when it does.
    return ScoreWithParent(grids_, level, query_, k, dx, dy, best_score_, parent_sums, sums);
  }

  // Nodes of `level`, each a block of 2^level x 2^level translations (cut at the window).
  void Descend(int level, Node* nodes, size_t count) {
    SortByBound(nodes, count);
    for (size_t i = 0; i < count; ++i) {
      const Node& node = nodes[i];
      if (!(node.bound > best_score_)) break;  // sorted: no later node can do better
      if (level == 0) {
        best_score_ = node.bound;
        best_ = LatticePose{node.k, node.dx, node.dy, node.bound};
        break;
      }
      const int half = 1 << (level - 1);
      // At most four children, on the stack: a vector (and stable_sort's buffer) per expanded
      // node was two allocations each, millions per global search.
      std::array<Node, 4> children;
      size_t num_children = 0;
      const double* parent_sums = Sums(level, node.slot);
      for (int oy = 0; oy <= half; oy += half) {
        for (int ox = 0; ox <= half; ox += half) {
          const int dx = node.dx + ox;
          const int dy = node.dy + oy;
          if (dx > window_.half_cells_x || dy > window_.half_cells_y) continue;
          const int slot = static_cast<int>(num_children);
          // Leaves need no sums (nothing descends from them).
          double* sums = level - 1 > 0 ? Sums(level - 1, slot) : nullptr;
          children[num_children++] =
              Node{node.k, dx, dy, Score(level - 1, node.k, dx, dy, parent_sums, sums), slot};
        }
      }
      Descend(level - 1, children.data(), num_children);
    }
  }

  // Best bound first, equal bounds in their given order (what std::stable_sort gives; an
  // insertion sort for the few children of a node, without its buffer).
  static void SortByBound(Node* nodes, size_t count) {
    if (count > 4) {
      std::stable_sort(nodes, nodes + count,
                       [](const Node& a, const Node& b) { return a.bound > b.bound; });
      return;
    }
    for (size_t i = 1; i < count; ++i) {
      const Node node = nodes[i];
      size_t j = i;
      for (; j > 0 && node.bound > nodes[j - 1].bound; --j) nodes[j] = nodes[j - 1];
      nodes[j] = node;
    }
  }

  const MaxGridPyramid& grids_;
  const DiscretisedQuery& query_;
  const SearchWindow& window_;
  double best_score_;
  LatticeSearchStats* stats_;
  std::optional<LatticePose> best_;
  size_t chunks_;
  std::vector<std::vector<double>> sums_;
};

}  // namespace

std::optional<LatticePose> BranchAndBound(const MaxGridPyramid& grids,
                                          const DiscretisedQuery& query, const SearchWindow& window,
                                          double min_score, LatticeSearchStats* stats) {
  return BranchAndBoundSearch(grids, query, window, min_score, stats).Run();
}

}  // namespace anchormap
