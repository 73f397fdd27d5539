#include "common/scan_matching/lattice_search.h"

#include <random>

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
  std::uniform_real_distribution<double> coord(0.0, 3.0);
  for (int trial = 0; trial < 24; ++trial) {
    const LikelihoodGrid grid = RandomGrid(30, 25, &rng, /*exact=*/true);
    const MaxGridPyramid pyramid(grid, 1 + trial % 5);
    ASSERT_TRUE(pyramid.exact_sums());
    PointCloud query;
    for (int i = 0; i < 20 + 9 * trial; ++i) query.push_back({coord(rng) - 1.5, coord(rng) - 1.5});
    SearchWindow window;
    window.center = Pose2(1.5, 1.2, 0.3 * trial);
    window.angle_step_rad = 0.05;
    window.half_angles = trial % 3;
    window.half_cells_x = 3 + trial % 7;
    window.half_cells_y = 2 + trial % 5;
    const DiscretisedQuery discretised(query, window, grid.geometry());
    const double min_score = trial % 3 == 0 ? 0.1 : 0.0;
    const auto all = ExhaustiveSearch(pyramid, discretised, window, min_score);
    const auto bnb = BranchAndBound(pyramid, discretised, window, min_score);
    ASSERT_EQ(all.has_value(), bnb.has_value()) << "trial " << trial;
    if (!all) continue;
    EXPECT_EQ(all->score, bnb->score) << "trial " << trial;
    EXPECT_EQ(ScoreOnLevel(pyramid, 0, discretised, bnb->k, bnb->dx, bnb->dy), bnb->score);
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
  const Pose2 pose = LatticeToPose(window, g.resolution, *best);
  EXPECT_NEAR(pose.x(), 1.05, 0.051);
  EXPECT_NEAR(pose.y(), 1.05, 0.051);
  // One step turns the far end of the L by 3 cm, less than a cell: +- 1 step is a tie.
  EXPECT_NEAR(pose.theta(), kPi / 2, 0.021);
  EXPECT_FALSE(BranchAndBound(pyramid, discretised, window, 1.0).has_value());
}

TEST(LatticeSearchTest, AngleStep) {
  // A point at 10 m moves by one 5 cm cell.
  const double step = AngleStepForRange(0.05, 10.0);
  EXPECT_NEAR(2.0 * 10.0 * std::sin(step / 2.0), 0.05, 1e-12);
  EXPECT_EQ(AngleStepForRange(0.05, 0.01), 0.1);
}

}  // namespace
}  // namespace anchormap
