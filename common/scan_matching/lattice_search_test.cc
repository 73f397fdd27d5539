#include "common/scan_matching/lattice_search.h"

#include <algorithm>
#include <cstdlib>
#include <limits>
#include <optional>
#include <random>
#include <stdexcept>
#include <vector>

#include <gtest/gtest.h>

#include "common/geometry/angle.h"

namespace anchormap {
namespace {

// `exact`: values 0 or in [2^-7, 1] (sums exact in any order: the vectorised path).
LikelihoodGrid RandomGrid(int width, int height, std::mt19937_64* rng, bool exact = false) {
  std::uniform_real_distribution<float> unit(0.0f, 1.0f);
  GridGeometry g;
  g.resolution = 0.1;
  g.width = width;
  g.height = height;
  std::vector<float> values(g.num_cells());
  for (float& v : values) {
    v = unit(*rng) < 0.2f ? unit(*rng) : 0.0f;
    if (exact && v > 0.0f) v = std::max(v, 1.0f / 128.0f);
  }
  return LikelihoodGrid(g, values);
}

// Trial `trial`'s query (20 + 9 x trial points in a 3 m square) and window on a RandomGrid
// of 30 x 25: more points and other window sizes and headings per trial (up to
// `max_half_angles` headings to each side).
struct QueryInWindow {
  PointCloud query;
  SearchWindow window;
};
QueryInWindow RandomQueryInWindow(int trial, int max_half_angles, std::mt19937_64* rng) {
  std::uniform_real_distribution<double> coord(0.0, 3.0);
  QueryInWindow q;
  for (int i = 0; i < 20 + 9 * trial; ++i) {
    q.query.push_back({coord(*rng) - 1.5, coord(*rng) - 1.5});
  }
  q.window.center = Pose2(1.5, 1.2, 0.3 * trial);
  q.window.angle_step_rad = 0.05;
  q.window.half_angles = trial % (max_half_angles + 1);
  q.window.half_cells_x = 3 + trial % 7;
  q.window.half_cells_y = 2 + trial % 5;
  return q;
}

TEST(LatticeSearchTest, BranchAndBoundEqualsExhaustiveSearch) {
  // Random grids and random queries: the best score is the same (to the last bit, the scores
  // are computed by the same function), and branch and bound scores fewer leaves.
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<double> coord(0.0, 3.0);
  int64_t leaves_bnb = 0;
  int64_t leaves_all = 0;
  for (int trial = 0; trial < 40; ++trial) {
    const LikelihoodGrid grid = RandomGrid(30, 25, &rng);
    const int levels = 1 + trial % 5;
    const MaxGridPyramid pyramid(grid, levels);
    PointCloud query;
    for (int i = 0; i < 15; ++i) query.push_back({coord(rng) - 1.5, coord(rng) - 1.5});
    SearchWindow window;
    window.center = Pose2(1.5, 1.2, 0.3 * trial);
    window.angle_step_rad = 0.05;
    window.half_angles = trial % 4;
    window.half_cells_x = 3 + trial % 7;
    window.half_cells_y = 2 + trial % 5;
    const DiscretisedQuery discretised(query, window, grid.geometry());
    LatticeSearchStats stats_all;
    LatticeSearchStats stats_bnb;
    const double min_score = trial % 3 == 0 ? 0.2 : 0.0;
    const auto all = ExhaustiveSearch(pyramid, discretised, window, min_score, &stats_all);
    const auto bnb = BranchAndBound(pyramid, discretised, window, min_score, &stats_bnb);
    ASSERT_EQ(all.has_value(), bnb.has_value()) << "trial " << trial;
    if (!all) continue;
    EXPECT_EQ(all->score, bnb->score) << "trial " << trial;
    EXPECT_EQ(ScoreOnLevel(pyramid, 0, discretised, bnb->k, bnb->dx, bnb->dy), bnb->score);
    EXPECT_LE(std::abs(bnb->dx), window.half_cells_x);
    EXPECT_LE(std::abs(bnb->dy), window.half_cells_y);
    EXPECT_LE(std::abs(bnb->k), window.half_angles);
    leaves_bnb += stats_bnb.leaves;
    leaves_all += stats_all.leaves;
  }
  EXPECT_LT(leaves_bnb, leaves_all / 2);
}

// The mean of the level's values at the query's shifted cells, one bounds-checked lookup at a
// time in the query's order: what ScoreOnLevel computed before its fast paths.
double NaiveScore(const MaxGridPyramid& grids, int level, const DiscretisedQuery& query, int k,
                  int dx, int dy) {
  double sum = 0.0;
  for (size_t i = 0; i < query.num_points(); ++i) {
    sum += grids.Value(level, query.xs(k)[i] + dx, query.ys(k)[i] + dy);
  }
  return sum / static_cast<double>(query.num_points());
}

TEST(LatticeSearchTest, FastScoresEqualTheNaiveSumToTheBit) {
  // Grids whose sums are exact in any order (values 0 or in [2^-7, 1], as a likelihood grid's:
  // the vectorised path) and grids with any values (the running sum): every level, shifts that
  // keep the query inside the grid and shifts that put it partly or wholly outside.
  std::mt19937_64 rng(11);
  std::uniform_real_distribution<double> within(0.3, 2.2);  // small shifts keep it inside
  std::uniform_real_distribution<double> beyond(-2.0, 5.0);
  std::uniform_real_distribution<float> unit(0.0f, 1.0f);
  for (int trial = 0; trial < 10; ++trial) {
    std::uniform_real_distribution<double>& coord = trial % 4 < 2 ? within : beyond;
    const bool exact = trial % 2 == 0;
    GridGeometry g;
    g.resolution = 0.1;
    g.width = 35;
    g.height = 28;
    std::vector<float> values(g.num_cells());
    for (float& v : values) {
      const float u = unit(rng);
      v = unit(rng) < 0.3f ? (exact ? std::max(u, 1.0f / 128.0f) : u * 1e-3f) : 0.0f;
    }
    const MaxGridPyramid pyramid(LikelihoodGrid(g, values), 4);
    EXPECT_EQ(pyramid.exact_sums(), exact);
    PointCloud query;
    for (int i = 0; i < 5 + 37 * trial; ++i) query.push_back({coord(rng), coord(rng)});
    SearchWindow window;
    window.center = Pose2(0.5, 0.4, 0.1 * trial);
    window.angle_step_rad = 0.03;
    window.half_angles = 1;
    const DiscretisedQuery discretised(query, window, g);
    for (int level = 0; level < 4; ++level) {
      for (int k = -1; k <= 1; ++k) {
        for (int dy = -40; dy <= 40; dy += 6) {
          for (int dx = -45; dx <= 45; dx += 7) {
            const double naive = NaiveScore(pyramid, level, discretised, k, dx, dy);
            ASSERT_EQ(ScoreOnLevel(pyramid, level, discretised, k, dx, dy), naive)
                << "trial " << trial << " level " << level << " k " << k << " " << dx << "," << dy;
            // Above a floor the score is finished; at or below it, the answer stays there.
            for (const double floor : {0.0, 0.5 * naive, naive, 0.2}) {
              const double above = ScoreOnLevelAbove(pyramid, level, discretised, k, dx, dy, floor);
              if (naive > floor) {
                ASSERT_EQ(above, naive);
              } else {
                ASSERT_LE(above, floor);
              }
            }
          }
        }
      }
    }
  }
}

TEST(LatticeSearchTest, BranchAndBoundEqualsExhaustiveSearchOnExactGrids) {
  // Grids whose sums are exact (the vectorised sums; a node's children are cut short by its
  // own running sums) and queries of more than one chunk of the sums (32 points): the same
  // best lattice pose as the exhaustive search, to the bit.
  std::mt19937_64 rng(13);
  for (int trial = 0; trial < 24; ++trial) {
    const LikelihoodGrid grid = RandomGrid(30, 25, &rng, /*exact=*/true);
    const MaxGridPyramid pyramid(grid, 1 + trial % 5);
    ASSERT_TRUE(pyramid.exact_sums());
    const auto [query, window] = RandomQueryInWindow(trial, 2, &rng);
    const DiscretisedQuery discretised(query, window, grid.geometry());
    const double min_score = trial % 3 == 0 ? 0.1 : 0.0;
    const auto all = ExhaustiveSearch(pyramid, discretised, window, min_score);
    const auto bnb = BranchAndBound(pyramid, discretised, window, min_score);
    // The inner nodes on the bytes: the same pose, to the bit.
    const ByteMaxGrids bytes(pyramid);
    const auto on_bytes = BranchAndBound(pyramid, discretised, window, min_score, nullptr, &bytes);
    ASSERT_EQ(all.has_value(), bnb.has_value()) << "trial " << trial;
    ASSERT_EQ(all.has_value(), on_bytes.has_value()) << "trial " << trial;
    if (!all) continue;
    EXPECT_EQ(all->score, bnb->score) << "trial " << trial;
    EXPECT_EQ(ScoreOnLevel(pyramid, 0, discretised, bnb->k, bnb->dx, bnb->dy), bnb->score);
    EXPECT_EQ(on_bytes->score, all->score) << "trial " << trial;
    EXPECT_EQ(on_bytes->k, all->k) << "trial " << trial;
    EXPECT_EQ(on_bytes->dx, all->dx) << "trial " << trial;
    EXPECT_EQ(on_bytes->dy, all->dy) << "trial " << trial;
  }
}

TEST(LatticeSearchTest, OnTheBytesOnlyLevelZeroIsRead) {
  // A pyramid whose float levels above 0 are not built (a reference searched only on the
  // bytes): the bytes built from its level 0 equal those of the built pyramid, branch and bound
  // on them (the centre first too, a local match's way) finds the exhaustive search's pose,
  // ties included, and a search on the floats refuses to run without the levels.
  std::mt19937_64 rng(29);
  for (int trial = 0; trial < 16; ++trial) {
    const LikelihoodGrid grid = RandomGrid(30, 25, &rng, /*exact=*/true);
    const int levels = 2 + trial % 6;
    const MaxGridPyramid built(grid, levels);
    const MaxGridPyramid base(LikelihoodGrid(grid), levels, /*build_levels=*/false);
    ASSERT_FALSE(base.levels_built());
    const ByteMaxGrids from_built(built);
    const ByteMaxGrids from_base(base);
    for (int h = 1; h < levels; ++h) {
      const ByteMaxGrids::LevelView a = from_built.level(h);
      const ByteMaxGrids::LevelView b = from_base.level(h);
      ASSERT_EQ(a.width, b.width);
      ASSERT_EQ(a.height, b.height);
      const size_t cells = static_cast<size_t>(a.width) * static_cast<size_t>(a.height) + 3;
      ASSERT_TRUE(std::equal(a.values, a.values + cells, b.values)) << "level " << h;
    }
    const auto [query, window] = RandomQueryInWindow(trial, 3, &rng);
    const DiscretisedQuery discretised(query, window, grid.geometry());
    const double min_score = trial % 3 == 0 ? 0.1 : 0.0;
    const auto all = ExhaustiveSearch(built, discretised, window, min_score);
    for (const bool centre_first : {false, true}) {
      const auto on_bytes =
          BranchAndBound(base, discretised, window, min_score, nullptr, &from_base, centre_first);
      ASSERT_EQ(all.has_value(), on_bytes.has_value()) << "trial " << trial;
      if (!all) continue;
      EXPECT_EQ(on_bytes->score, all->score) << "trial " << trial;
      EXPECT_EQ(on_bytes->k, all->k) << "trial " << trial;
      EXPECT_EQ(on_bytes->dx, all->dx) << "trial " << trial;
      EXPECT_EQ(on_bytes->dy, all->dy) << "trial " << trial;
    }
    EXPECT_THROW(BranchAndBound(base, discretised, window, min_score), std::logic_error);
  }
}

// Expects `found` where exhaustive search found `all`: both or neither, the same score and pose.
void ExpectSameLatticePose(const std::optional<LatticePose>& found,
                           const std::optional<LatticePose>& all) {
  EXPECT_EQ(all.has_value(), found.has_value());
  if (all && found) {
    EXPECT_EQ(found->score, all->score);
    EXPECT_EQ(found->k, all->k);
    EXPECT_EQ(found->dx, all->dx);
    EXPECT_EQ(found->dy, all->dy);
  }
}

// Expects branch and bound to find exhaustive search's lattice pose (score, then the first in
// (k, dy, dx) order among equals), scoring no more leaves (as many with one level: no bounds);
// with `bytes`, also with its inner nodes on them.
void ExpectSamePose(const MaxGridPyramid& pyramid, const DiscretisedQuery& query,
                    const SearchWindow& window, double min_score,
                    const ByteMaxGrids* bytes = nullptr) {
  LatticeSearchStats all_stats;
  LatticeSearchStats bnb_stats;
  const auto all = ExhaustiveSearch(pyramid, query, window, min_score, &all_stats);
  const auto bnb = BranchAndBound(pyramid, query, window, min_score, &bnb_stats);
  ExpectSameLatticePose(bnb, all);
  EXPECT_LE(bnb_stats.leaves, all_stats.leaves);
  if (pyramid.num_levels() > 1) {
    EXPECT_LT(bnb_stats.leaves, all_stats.leaves);
  }
  // The window's centre scored first (a local match's guess): the same pose, ties included.
  const auto centre_first =
      BranchAndBound(pyramid, query, window, min_score, nullptr, nullptr, /*centre_first=*/true);
  ExpectSameLatticePose(centre_first, all);
  if (bytes == nullptr) return;
  // The inner nodes on the bytes (the global search's way): the same pose.
  LatticeSearchStats byte_stats;
  const auto on_bytes = BranchAndBound(pyramid, query, window, min_score, &byte_stats, bytes);
  ExpectSameLatticePose(on_bytes, all);
  EXPECT_LE(byte_stats.leaves, all_stats.leaves);
}

TEST(LatticeSearchTest, HeadingGroupsFindTheExhaustivePoseOnEveryLevelCount) {
  // A wall-like grid (walls of exact values, 0 elsewhere), many headings at the step that moves
  // the farthest point by one cell (groups of headings bound together from 6 levels on), and at
  // three times that step (groups too wide for their level: bounded higher up, or not at all).
  std::mt19937_64 rng(17);
  GridGeometry g;
  g.resolution = 0.1;
  g.width = 70;
  g.height = 60;
  std::vector<float> values(g.num_cells(), 0.0f);
  std::uniform_int_distribution<int> cell_x(0, g.width - 1);
  std::uniform_int_distribution<int> cell_y(0, g.height - 1);
  std::uniform_real_distribution<float> unit(0.0f, 1.0f);
  for (int wall = 0; wall < 12; ++wall) {
    const int x = cell_x(rng);
    const int y = cell_y(rng);
    const bool along_x = wall % 2 == 0;
    for (int i = 0; i < 15; ++i) {
      const int wx = along_x ? std::min(x + i, g.width - 1) : x;
      const int wy = along_x ? y : std::min(y + i, g.height - 1);
      values[g.Index(wx, wy)] = std::max(1.0f / 128.0f, unit(rng));
    }
  }
  const LikelihoodGrid grid(g, values);
  std::uniform_real_distribution<double> coord(-2.5, 2.5);
  PointCloud query;
  for (int i = 0; i < 50; ++i) query.push_back({coord(rng), coord(rng)});
  const double step = AngleStepForRange(g.resolution, MaxPointRange(query));
  for (const int levels : {1, 5, 6, 7}) {
    const MaxGridPyramid pyramid(grid, levels);
    ASSERT_TRUE(pyramid.exact_sums());
    const ByteMaxGrids bytes(pyramid);
    for (const double step_factor : {1.0, 3.0}) {
      SearchWindow window;
      window.center = Pose2(3.5, 3.0, 0.2 * levels);
      window.angle_step_rad = step_factor * step;
      window.half_angles = 40;
      window.half_cells_x = 20;
      window.half_cells_y = 15;
      const DiscretisedQuery discretised(query, window, g);
      for (const double min_score : {0.0, 0.3}) {
        SCOPED_TRACE(testing::Message()
                     << levels << " levels, step x" << step_factor << ", min score " << min_score);
        // The bytes once (a global search's levels and step): the random walls' many close
        // bounds cost them more nodes than real maps do.
        ExpectSamePose(pyramid, discretised, window, min_score,
                       levels == 7 && step_factor == 1.0 ? &bytes : nullptr);
      }
    }
  }
}

TEST(LatticeSearchTest, LazyRootsVisitTheEagerRootsNodesAndFindTheirPose) {
  // Pyramids too shallow for heading groups (3-5 levels: single-heading roots, the loop
  // closures' wide searches), windows of hundreds to thousands of roots on rooms of walls: the
  // lazy roots give the eager descent's pose and score, and its stats to the node (every root
  // counted, the same nodes below them), at bars from none to above the best; against
  // exhaustive search on the small windows. Fails if a lazy root's bound, its sums or the order
  // the roots are descended in differed.
  std::mt19937_64 rng(29);
  std::uniform_int_distribution<int> length(5, 40);
  std::uniform_real_distribution<float> unit(0.0f, 1.0f);
  int lazy_cases = 0;
  for (int trial = 0; trial < 16; ++trial) {
    GridGeometry g;
    g.resolution = 0.05;
    g.width = 120 + 10 * trial;
    g.height = 100 + 7 * trial;
    std::vector<float> values(g.num_cells(), 0.0f);
    std::uniform_int_distribution<int> cell_x(0, g.width - 1);
    std::uniform_int_distribution<int> cell_y(0, g.height - 1);
    for (int wall = 0; wall < 30; ++wall) {
      const int x = cell_x(rng);
      const int y = cell_y(rng);
      const bool along_x = wall % 2 == 0;
      for (int i = 0; i < length(rng); ++i) {
        const int wx = along_x ? std::min(x + i, g.width - 1) : x;
        const int wy = along_x ? y : std::min(y + i, g.height - 1);
        // Plateaus of equal values too, and in odd trials only three values (equal bounds
        // between roots and groups, ties between leaves).
        const float random = std::max(1.0f / 128.0f, unit(rng));
        const float quantised = random < 0.4f ? 0.25f : random < 0.8f ? 0.5f : 1.0f;
        values[g.Index(wx, wy)] = wall % 3 == 0 ? 1.0f : trial % 2 == 1 ? quantised : random;
      }
    }
    const LikelihoodGrid grid(g, values);
    // A scan of the room from near its middle: points on the walls, a few off them.
    PointCloud query;
    const Eigen::Vector2d origin(0.5 * g.width * g.resolution, 0.5 * g.height * g.resolution);
    for (int y = 0; y < g.height; ++y) {
      for (int x = 0; x < g.width; ++x) {
        if (values[g.Index(x, y)] > 0.0f && unit(rng) < 0.3f) {
          query.push_back(g.CellCentre(x, y) - origin);
        }
      }
    }
    for (int i = 0; i < 10; ++i) query.push_back({unit(rng) - 0.5, unit(rng) - 0.5});
    const int levels = 3 + trial % 3;
    const MaxGridPyramid pyramid(grid, levels);
    ASSERT_TRUE(pyramid.exact_sums());
    SearchWindow window;
    window.center =
        Pose2(origin.x() + 0.1 * (trial % 4), origin.y() - 0.05 * (trial % 3), 0.01 * trial);
    window.angle_step_rad = AngleStepForRange(g.resolution, MaxPointRange(query));
    window.half_angles = trial < 6 ? 6 + 5 * trial : 60 + 10 * trial;
    window.half_cells_x = 10 + 4 * trial;
    window.half_cells_y = 8 + 3 * trial;
    const DiscretisedQuery discretised(query, window, g);
    const bool small = trial < 4;
    std::optional<LatticePose> all;
    if (small) all = ExhaustiveSearch(pyramid, discretised, window, 0.0);
    for (const double min_score : {0.0, 0.2, 0.5, 0.999}) {
      for (const bool centre_first : {false, true}) {
        SCOPED_TRACE(testing::Message() << "trial " << trial << ", " << levels << " levels, bar "
                                        << min_score << (centre_first ? ", centre first" : ""));
        LatticeSearchStats eager_stats;
        LatticeSearchStats lazy_stats;
        const auto eager = BranchAndBound(pyramid, discretised, window, min_score, &eager_stats,
                                          nullptr, centre_first, /*lazy_roots=*/false);
        const auto lazy = BranchAndBound(pyramid, discretised, window, min_score, &lazy_stats,
                                         nullptr, centre_first, /*lazy_roots=*/true);
        ExpectSameLatticePose(lazy, eager);
        EXPECT_EQ(lazy_stats.scored_nodes, eager_stats.scored_nodes);
        EXPECT_EQ(lazy_stats.leaves, eager_stats.leaves);
        if (small && min_score == 0.0) ExpectSameLatticePose(lazy, all);
        if (lazy && lazy->score > 0.3) ++lazy_cases;
      }
    }
  }
  EXPECT_GT(lazy_cases, 40);  // most searches found a pose well above the lowest bars
}

TEST(LatticeSearchTest, MaxCellMoveIsTheLargestDifference) {
  // Against the definition, one difference at a time: lengths around the vectorised eight
  // (tails), differences of both signs, the largest anywhere.
  std::mt19937_64 rng(5);
  std::uniform_int_distribution<int32_t> cell(-4000, 4000);
  for (size_t n = 0; n <= 41; ++n) {
    for (int trial = 0; trial < 20; ++trial) {
      std::vector<int32_t> a(n);
      std::vector<int32_t> b(n);
      for (size_t i = 0; i < n; ++i) {
        a[i] = cell(rng);
        b[i] = a[i] + cell(rng) % 9;
      }
      if (n > 0 && trial % 2 == 0) b[rng() % n] = a[0] - 3000;  // one far move, somewhere
      int expected = 0;
      for (size_t i = 0; i < n; ++i) expected = std::max(expected, std::abs(a[i] - b[i]));
      ASSERT_EQ(MaxCellMove(a.data(), b.data(), n), expected) << n << " " << trial;
    }
  }
}

TEST(LatticeSearchTest, TiesGoToTheFirstPoseInExhaustiveOrder) {
  // A plateau of equal values: many lattice poses score 1 exactly; every level count and
  // window returns the one exhaustive search meets first.
  GridGeometry g;
  g.resolution = 0.1;
  g.width = 50;
  g.height = 40;
  std::vector<float> values(g.num_cells(), 0.0f);
  for (int y = 10; y < 30; ++y) {
    for (int x = 12; x < 40; ++x) values[g.Index(x, y)] = 0.5f;
  }
  const LikelihoodGrid grid(g, values);
  PointCloud query;
  for (int i = 0; i < 40; ++i) query.push_back({0.02 * (i % 8) - 0.07, 0.02 * (i / 8) - 0.05});
  for (int levels = 1; levels <= 7; levels += 2) {
    const MaxGridPyramid pyramid(grid, levels);
    SearchWindow window;
    window.center = Pose2(2.5, 2.0, 0.0);
    window.angle_step_rad = AngleStepForRange(g.resolution, MaxPointRange(query));
    window.half_angles = 12;
    window.half_cells_x = 24;
    window.half_cells_y = 19;
    const DiscretisedQuery discretised(query, window, g);
    SCOPED_TRACE(testing::Message() << levels << " levels");
    const ByteMaxGrids bytes(pyramid);
    ExpectSamePose(pyramid, discretised, window, 0.0, &bytes);
  }
}

TEST(LatticeSearchTest, FindsAPlantedPatternAndNothingAboveAnImpossibleScore) {
  GridGeometry g;
  g.resolution = 0.1;
  g.width = 40;
  g.height = 40;
  std::vector<float> values(g.num_cells(), 0.0f);
  // An L of cells at (10..24, 10) and (10, 10..21).
  for (int i = 0; i < 15; ++i) values[g.Index(10 + i, 10)] = 1.0f;
  for (int i = 0; i < 12; ++i) values[g.Index(10, 10 + i)] = 1.0f;
  const LikelihoodGrid grid(g, values);
  const MaxGridPyramid pyramid(grid, 4);
  // The same L in the query's frame, seen from (1.05, 1.05) heading 90 degrees.
  PointCloud query;
  const Pose2 truth(1.05, 1.05, kPi / 2);
  for (int i = 0; i < 15; ++i)
    query.push_back(truth.Inverse().TransformPoint({1.05 + 0.1 * i, 1.05}));
  for (int i = 1; i < 12; ++i)
    query.push_back(truth.Inverse().TransformPoint({1.05, 1.05 + 0.1 * i}));
  SearchWindow window;
  window.center = Pose2(0.75, 1.25, kPi / 2 - 0.2);
  window.angle_step_rad = 0.02;
  window.half_angles = 20;
  window.half_cells_x = 6;
  window.half_cells_y = 6;
  const DiscretisedQuery discretised(query, window, g);
  const auto best = BranchAndBound(pyramid, discretised, window, 0.0);
  ASSERT_TRUE(best.has_value());
  EXPECT_DOUBLE_EQ(best->score, 1.0);
  // Of the tied poses, the exhaustive search's first.
  const auto first = ExhaustiveSearch(pyramid, discretised, window, 0.0);
  ASSERT_TRUE(first.has_value());
  EXPECT_EQ(best->k, first->k);
  EXPECT_EQ(best->dx, first->dx);
  EXPECT_EQ(best->dy, first->dy);
  const Pose2 pose = LatticeToPose(window, g.resolution, *best);
  EXPECT_NEAR(pose.x(), 1.05, 0.051);
  EXPECT_NEAR(pose.y(), 1.05, 0.051);
  // One step turns the far end of the L by 3 cm, less than a cell: +- 1 step is a tie.
  EXPECT_NEAR(pose.theta(), kPi / 2, 0.021);
  EXPECT_FALSE(BranchAndBound(pyramid, discretised, window, 1.0).has_value());
}

TEST(LatticeSearchTest, DiscretisedCellsAreCellOfToTheBit) {
  // Every heading's cells and box are GridGeometry::CellOf of the point at that heading's pose
  // (the vectorised path takes four points at a time, the rest one by one): random points, ones
  // on cell borders at the centre heading, and points far outside the grid on both sides.
  GridGeometry g;
  g.origin = {-3.05, 1.7};
  g.resolution = 0.05;
  g.width = 200;
  g.height = 150;
  std::mt19937_64 rng(21);
  std::uniform_real_distribution<double> coordinate(-12.0, 12.0);
  for (const size_t size : {0, 1, 3, 4, 7, 181, 362}) {
    PointCloud query;
    for (size_t i = 0; i < size; ++i) query.emplace_back(coordinate(rng), coordinate(rng));
    SearchWindow window;
    window.center = Pose2(0.35, -0.2, 0.3);
    window.angle_step_rad = 0.013;
    window.half_angles = 5;
    if (size == 362) {
      // Cell borders at heading 0 (the centre's rotation undone) and far points.
      window.center = Pose2(0.0, 0.0, 0.0);
      for (size_t i = 0; i < 100; ++i) {
        query[i] = g.origin + g.resolution * Eigen::Vector2d(static_cast<double>(i % 10) - 3.0,
                                                             static_cast<double>(i / 10));
      }
      query[100] = {1e7, -1e7};
      query[101] = {-5e7, 3e7};  // cells within +-2^31 (the casts are exact there)
    }
    const DiscretisedQuery discretised(query, window, g);
    ASSERT_EQ(discretised.num_points(), size);
    for (int k = -window.half_angles; k <= window.half_angles; ++k) {
      const Pose2 pose(window.center.x(), window.center.y(),
                       window.center.theta() + k * window.angle_step_rad);
      Eigen::Vector2i min = Eigen::Vector2i::Constant(std::numeric_limits<int>::max());
      Eigen::Vector2i max = Eigen::Vector2i::Constant(std::numeric_limits<int>::min());
      for (size_t i = 0; i < size; ++i) {
        const Eigen::Vector2i cell = g.CellOf(pose.rotation() * query[i] + pose.translation());
        ASSERT_EQ(discretised.xs(k)[i], cell.x()) << size << " " << k << " " << i;
        ASSERT_EQ(discretised.ys(k)[i], cell.y()) << size << " " << k << " " << i;
        min = min.cwiseMin(cell);
        max = max.cwiseMax(cell);
      }
      EXPECT_EQ(discretised.box(k).min, min);
      EXPECT_EQ(discretised.box(k).max, max);
    }
  }
}

TEST(LatticeSearchTest, AngleStep) {
  // A point at 10 m moves by one 5 cm cell.
  const double step = AngleStepForRange(0.05, 10.0);
  EXPECT_NEAR(2.0 * 10.0 * std::sin(step / 2.0), 0.05, 1e-12);
  EXPECT_EQ(AngleStepForRange(0.05, 0.01), 0.1);
}

}  // namespace
}  // namespace anchormap
