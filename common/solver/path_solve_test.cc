#include "common/solver/path_solve.h"
#include "common/solver/sparse_r_testing.h"

#include <random>

#include <gtest/gtest.h>
#include <Eigen/Dense>

namespace anchormap {
namespace {

// Two chains, positions 0-19 and 20-39 (a closure inside the first), both tied to
// position 40: the elimination tree has two branches, so a gradient on the first chain
// reaches that chain's rows from it on and the root, not the second chain.
SparseR TwoBranches(std::mt19937* rng) {
  SparseR r;
  r.Append(41);
  r.Eliminate(RandomBetweenRows(40, -1, rng), nullptr);
  for (int p = 0; p < 40; ++p) {
    r.Eliminate(RandomBetweenRows(p, p == 0 || p == 20 ? -1 : p - 1, rng), nullptr);
  }
  r.Eliminate(RandomBetweenRows(19, 40, rng), nullptr);
  r.Eliminate(RandomBetweenRows(39, 40, rng), nullptr);
  r.Eliminate(RandomBetweenRows(8, 15, rng), nullptr);
  return r;
}

TEST(PathSolveTest, SolvesOnlyThePathsOfTheGradientAndMatchesADenseSolve) {
  std::mt19937 rng(3);
  const SparseR r = TwoBranches(&rng);
  const std::vector<std::pair<int, Eigen::Vector3d>> g = {
      {12, Eigen::Vector3d(0.5, -1.0, 2.0)},
      {5, Eigen::Vector3d(1.0, 0.25, -0.5)},
      {5, Eigen::Vector3d(-0.5, 1.0, 0.0)}};  // a repeated position adds up
  Eigen::VectorXd dense_g = Eigen::VectorXd::Zero(3 * r.size());
  for (const auto& [p, v] : g) dense_g.segment<3>(3 * p) += v;
  const Eigen::VectorXd y = DenseR(r).transpose().triangularView<Eigen::Lower>().solve(dense_g);

  PathSolve solve;
  const double norm2 = solve.SquaredNorm(r, g);
  EXPECT_NEAR(norm2, y.squaredNorm(), 1e-12 * y.squaredNorm());
  EXPECT_GT(norm2, 0.0);
  // Rows 5-19 and the root: the rows where y is not zero.
  EXPECT_EQ(solve.rows_solved(), 16);
  EXPECT_EQ(y.head(3 * 5).cwiseAbs().maxCoeff(), 0.0);
  EXPECT_EQ(y.segment(3 * 20, 3 * 20).cwiseAbs().maxCoeff(), 0.0);
}

TEST(PathSolveTest, StopsOncePastTheLimitAndTheNextSolveIsExact) {
  std::mt19937 rng(5);
  const SparseR r = TwoBranches(&rng);
  const std::vector<std::pair<int, Eigen::Vector3d>> g = {{2, Eigen::Vector3d(1.0, 2.0, -1.0)}};
  PathSolve solve;
  const double full = solve.SquaredNorm(r, g);
  EXPECT_EQ(solve.rows_solved(), 19);  // rows 2-19 and the root

  const double stopped = solve.SquaredNorm(r, g, 0.25 * full);
  EXPECT_GT(stopped, 0.25 * full);
  EXPECT_LE(stopped, full);
  EXPECT_LT(solve.rows_solved(), 19);
  // The work space is clean again: the same solve, the same bits.
  EXPECT_EQ(solve.SquaredNorm(r, g), full);
  EXPECT_EQ(solve.SquaredNorm(r, {{30, Eigen::Vector3d(1.0, 0.0, 0.0)}}, 1e300),
            solve.SquaredNorm(r, {{30, Eigen::Vector3d(1.0, 0.0, 0.0)}}));
  EXPECT_EQ(solve.rows_solved(), 11);  // rows 30-39 and the root
}

}  // namespace
}  // namespace anchormap
