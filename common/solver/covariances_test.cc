#include "common/solver/covariances.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <memory>
#include <random>
#include <stdexcept>
#include <vector>

#include <gtest/gtest.h>
#include <Eigen/Dense>

namespace anchormap {
namespace {

// A random R as a pose graph's: a chain of n poses with `closures` random loop closures,
// eliminated into R, and the dense inverse of R^T R to compare against.
struct RandomR {
  std::shared_ptr<SparseR> r;
  Eigen::MatrixXd sigma;
};

RandomR MakeChainWithLoopClosures(int n, int closures, unsigned seed) {
  std::mt19937 rng(seed);
  auto r = std::make_shared<SparseR>();
  r->Append(n);
  for (int p = 0; p < n; ++p) {
    NewRows rows;
    rows.blocks.emplace_back(p, Eigen::Matrix3d::Identity() * 2 + 0.2 * Eigen::Matrix3d::Random());
    if (p > 0) rows.blocks.emplace_back(p - 1, Eigen::Matrix3d::Random());
    r->Eliminate(rows, nullptr);
  }
  for (int k = 0; k < closures; ++k) {
    NewRows rows;
    const int a = std::uniform_int_distribution<int>(0, n - 2)(rng);
    rows.blocks.emplace_back(a, Eigen::Matrix3d::Random());
    rows.blocks.emplace_back(std::uniform_int_distribution<int>(a + 1, n - 1)(rng),
                             Eigen::Matrix3d::Random());
    r->Eliminate(rows, nullptr);
  }
  Eigen::MatrixXd R = Eigen::MatrixXd::Zero(3 * n, 3 * n);
  for (int p = 0; p < n; ++p) {
    R.block<3, 3>(3 * p, 3 * p) = r->row(p).diagonal;
    for (const auto& [q, block] : r->row(p).right) R.block<3, 3>(3 * p, 3 * q) = block;
  }
  return {r, (R.transpose() * R).inverse()};
}

TEST(CovarianceRecoveryTest, EveryBlockEqualsTheDenseInverse) {
  const int n = 25;
  const auto [r, sigma] = MakeChainWithLoopClosures(n, 15, 9);

  CovarianceRecovery recovery(r);
  // Marginals and pairs in R's pattern first (the cheap case), then any pair.
  for (int l = n - 1; l >= 0; --l) {
    EXPECT_LT((recovery.Block(l, l) - sigma.block<3, 3>(3 * l, 3 * l)).cwiseAbs().maxCoeff(), 1e-9);
  }
  for (int i = 0; i < n; ++i) {
    for (int l = 0; l < n; ++l) {
      EXPECT_LT((recovery.Block(i, l) - sigma.block<3, 3>(3 * i, 3 * l)).cwiseAbs().maxCoeff(),
                1e-9)
          << i << "," << l;
    }
  }
  const Eigen::MatrixXd joint = recovery.Joint({n - 1, 3, 17});
  EXPECT_LT((joint.block<3, 3>(3, 6) - sigma.block<3, 3>(9, 51)).cwiseAbs().maxCoeff(), 1e-9);
  EXPECT_LT((joint - joint.transpose()).cwiseAbs().maxCoeff(), 1e-12);
}

TEST(CovarianceRecoveryTest, LastBlockNeedsNoOtherEntries) {
  auto r = std::make_shared<SparseR>();
  r->Append(3);
  for (int p = 0; p < 3; ++p) {
    NewRows rows;
    rows.blocks.emplace_back(p, Eigen::Matrix3d::Identity() * (p + 1.0));
    if (p > 0) rows.blocks.emplace_back(p - 1, Eigen::Matrix3d::Identity());
    r->Eliminate(rows, nullptr);
  }
  CovarianceRecovery recovery(r);
  recovery.Block(2, 2);
  EXPECT_EQ(recovery.memoised(), 1u);  // only the anchor-last block: no recursion
}

// Thousands of blocks: the memo grows (and rehashes) several times; every block, computed
// before or after a growth, stays the dense inverse's, and asking again changes nothing.
TEST(CovarianceRecoveryTest, BlocksSurviveTheMemoGrowing) {
  const int n = 90;
  const auto [r, sigma] = MakeChainWithLoopClosures(n, 30, 4);

  CovarianceRecovery recovery(r);
  std::vector<Eigen::Matrix3d> first;
  for (int i = 0; i < n; ++i) {
    for (int l = i; l < n; ++l) first.push_back(recovery.Block(i, l));
  }
  EXPECT_EQ(recovery.memoised(), static_cast<size_t>(n * (n + 1) / 2));
  size_t k = 0;
  for (int i = 0; i < n; ++i) {
    for (int l = i; l < n; ++l, ++k) {
      EXPECT_EQ(recovery.Block(i, l), first[k]) << i << "," << l;
      if (l > i) {
        EXPECT_EQ(recovery.Block(l, i), first[k].transpose()) << l << "," << i;
      }
      EXPECT_LT((first[k] - sigma.block<3, 3>(3 * i, 3 * l)).cwiseAbs().maxCoeff(), 1e-9)
          << i << "," << l;
    }
  }
}

// J Sigma J^T by one sparse solve equals the dense projection for any positions (repeated
// ones too), in any order, and a refused call leaves nothing behind for the next one.
TEST(CovarianceProjectionTest, EqualsTheDenseProjectionForAnyPositions) {
  const int n = 60;
  const auto [r, sigma] = MakeChainWithLoopClosures(n, 25, 11);
  std::mt19937 rng(3);
  CovarianceProjection projected;
  CovarianceRecovery recovery(r);
  double worst_dense = 0.0, worst_recursion = 0.0;
  for (int query = 0; query < 300; ++query) {
    const int k = 1 + query % 4;
    std::vector<int> positions;
    std::vector<Eigen::Matrix3d> jacobians;
    Eigen::MatrixXd J = Eigen::MatrixXd::Zero(3, 3 * n);
    for (int s = 0; s < k; ++s) {
      positions.push_back(std::uniform_int_distribution<int>(0, n - 1)(rng));
      jacobians.push_back(Eigen::Matrix3d::Random());
      J.block<3, 3>(0, 3 * positions.back()) += jacobians.back();
    }
    const Eigen::Matrix3d expected = J * sigma * J.transpose();
    const Eigen::Matrix3d actual = projected.Compute(*r, positions, jacobians);
    const double scale = expected.cwiseAbs().maxCoeff();
    worst_dense = std::max(worst_dense, (actual - expected).cwiseAbs().maxCoeff() / scale);
    // The block recursion's answer for the same Jacobian.
    Eigen::MatrixXd J_joint(3, 3 * k);
    for (int s = 0; s < k; ++s) J_joint.block<3, 3>(0, 3 * s) = jacobians[s];
    const Eigen::Matrix3d by_blocks = J_joint * recovery.Joint(positions) * J_joint.transpose();
    worst_recursion = std::max(worst_recursion, (actual - by_blocks).cwiseAbs().maxCoeff() / scale);
    EXPECT_EQ(actual, actual.transpose());
  }
  EXPECT_LT(worst_dense, 1e-9);
  EXPECT_LT(worst_recursion, 1e-12);

  EXPECT_THROW(
      projected.Compute(*r, {3, n}, {Eigen::Matrix3d::Identity(), Eigen::Matrix3d::Identity()}),
      std::out_of_range);
  EXPECT_THROW(projected.Compute(*r, {3}, {}), std::invalid_argument);
  const Eigen::Matrix3d marginal = projected.Compute(*r, {3}, {Eigen::Matrix3d::Identity()});
  const Eigen::Matrix3d expected_marginal = sigma.block(9, 9, 3, 3);
  EXPECT_LT((marginal - expected_marginal).cwiseAbs().maxCoeff(),
            1e-9 * expected_marginal.cwiseAbs().maxCoeff());
}

// The last position has no ancestor: its marginal is its own diagonal block's, which the
// solve reaches without visiting any other row.
TEST(CovarianceProjectionTest, TheLastPositionNeedsOnlyItsDiagonalBlock) {
  const auto [r, sigma] = MakeChainWithLoopClosures(40, 10, 5);
  CovarianceProjection projected;
  const Eigen::Matrix3d R_ll = r->row(39).diagonal;
  const Eigen::Matrix3d expected = (R_ll.transpose() * R_ll).inverse();
  EXPECT_LT(
      (projected.Compute(*r, {39}, {Eigen::Matrix3d::Identity()}) - expected).cwiseAbs().maxCoeff(),
      1e-12 * expected.cwiseAbs().maxCoeff());
}

// Random queries of 1-4 positions (repeats within a query allowed) and Jacobians.
struct Query {
  std::vector<int> positions;
  std::vector<Eigen::Matrix3d> jacobians;
};
std::vector<Query> RandomQueries(int n, int count, unsigned seed) {
  std::mt19937 rng(seed);
  std::vector<Query> queries(count);
  for (int q = 0; q < count; ++q) {
    for (int s = 0; s <= q % 4; ++s) {
      queries[q].positions.push_back(std::uniform_int_distribution<int>(0, n - 1)(rng));
      queries[q].jacobians.push_back(Eigen::Matrix3d::Random());
    }
  }
  return queries;
}

bool SameBits(const Eigen::Matrix3d& a, const Eigen::Matrix3d& b) {
  return std::memcmp(a.data(), b.data(), sizeof(double) * 9) == 0;
}

// A query asked again of the same R is answered from the memo with the bits a fresh solve
// gives; once R changes (new rows eliminated into it) it is solved again, and again
// gives a fresh solve's bits, the new matrix's answer.
TEST(CovarianceProjectionTest, TheMemoGivesTheSolvesBitsUntilRChanges) {
  const int n = 50;
  const auto [r, sigma] = MakeChainWithLoopClosures(n, 20, 17);
  const std::vector<Query> queries = RandomQueries(n, 40, 9);
  CovarianceProjection projected;
  std::vector<Eigen::Matrix3d> first;
  for (const Query& q : queries) first.push_back(projected.Compute(*r, q.positions, q.jacobians));
  EXPECT_EQ(projected.computed(), 40);
  EXPECT_EQ(projected.memo_hits(), 0);
  for (size_t i = 0; i < queries.size(); ++i) {
    CovarianceProjection fresh;
    EXPECT_TRUE(SameBits(first[i], fresh.Compute(*r, queries[i].positions, queries[i].jacobians)));
    EXPECT_TRUE(
        SameBits(first[i], projected.Compute(*r, queries[i].positions, queries[i].jacobians)));
  }
  EXPECT_EQ(projected.computed(), 40);
  EXPECT_EQ(projected.memo_hits(), 40);
  // A Jacobian that differs in one bit is another query.
  Query nudged = queries[5];
  nudged.jacobians[0](1, 2) = std::nextafter(nudged.jacobians[0](1, 2), 10.0);
  projected.Compute(*r, nudged.positions, nudged.jacobians);
  EXPECT_EQ(projected.computed(), 41);

  // A loop closure between the first and the last pose: every answer moves.
  NewRows closure;
  closure.blocks.emplace_back(0, Eigen::Matrix3d::Identity());
  closure.blocks.emplace_back(n - 1, -Eigen::Matrix3d::Identity());
  r->Eliminate(closure, nullptr);
  int moved = 0;
  for (size_t i = 0; i < queries.size(); ++i) {
    CovarianceProjection fresh;
    const Eigen::Matrix3d now = projected.Compute(*r, queries[i].positions, queries[i].jacobians);
    EXPECT_TRUE(SameBits(now, fresh.Compute(*r, queries[i].positions, queries[i].jacobians)));
    moved += SameBits(now, first[i]) ? 0 : 1;
  }
  EXPECT_EQ(projected.computed(), 81);
  EXPECT_EQ(moved, 40);
  // A copy of R is another matrix (its own instance): solved, not remembered.
  const SparseR copy = *r;
  projected.Compute(copy, queries[0].positions, queries[0].jacobians);
  EXPECT_EQ(projected.computed(), 82);
}

// The marginals of several positions, solved side by side, have each position's own
// solve's bits (Compute with J = I), repeated and unordered positions included, and the
// work space is left clean for the next call.
TEST(CovarianceProjectionTest, MarginalsSideBySideHaveEachSolvesBits) {
  const int n = 70;
  const auto [r, sigma] = MakeChainWithLoopClosures(n, 30, 23);
  CovarianceProjection projected;
  const std::vector<std::vector<int>> sets = {{69}, {0, 69, 35}, {12, 12, 40, 3, 55, 68}, {}};
  for (int round = 0; round < 2; ++round) {
    for (const std::vector<int>& positions : sets) {
      const std::vector<Eigen::Matrix3d> marginals = projected.Marginals(*r, positions);
      ASSERT_EQ(marginals.size(), positions.size());
      for (size_t g = 0; g < positions.size(); ++g) {
        CovarianceProjection alone;
        const int p = positions[g];
        EXPECT_TRUE(SameBits(marginals[g], alone.Compute(*r, {p}, {Eigen::Matrix3d::Identity()})));
        const Eigen::Matrix3d expected = sigma.block<3, 3>(3 * p, 3 * p);
        EXPECT_LT((marginals[g] - expected).cwiseAbs().maxCoeff(),
                  1e-9 * expected.cwiseAbs().maxCoeff());
      }
    }
  }
  EXPECT_THROW(projected.Marginals(*r, {4, n}), std::out_of_range);
  CovarianceProjection alone;
  EXPECT_TRUE(SameBits(projected.Marginals(*r, {7})[0],
                       alone.Compute(*r, {7}, {Eigen::Matrix3d::Identity()})));
}

// Queries solved side by side have each query's own solve's bits (repeated positions and
// a query asked twice in one call included); they are remembered (Compute then answers
// from the memo, the same bits), remembered ones are not solved again, and the work space
// is left clean for the next call.
TEST(CovarianceProjectionTest, QueriesSideBySideHaveEachSolvesBits) {
  const int n = 70;
  const auto [r, sigma] = MakeChainWithLoopClosures(n, 30, 29);
  const std::vector<Query> random = RandomQueries(n, 24, 31);
  std::vector<CovarianceProjection::Query> queries;
  for (const Query& q : random) queries.push_back({q.positions, q.jacobians});
  queries.push_back(queries[3]);  // asked twice in one call
  CovarianceProjection projected;
  const std::vector<Eigen::Matrix3d> together = projected.ComputeSideBySide(*r, queries);
  ASSERT_EQ(together.size(), queries.size());
  EXPECT_EQ(projected.computed(), 25);
  for (size_t g = 0; g < queries.size(); ++g) {
    CovarianceProjection alone;
    EXPECT_TRUE(
        SameBits(together[g], alone.Compute(*r, queries[g].positions, queries[g].jacobians)));
    EXPECT_TRUE(
        SameBits(together[g], projected.Compute(*r, queries[g].positions, queries[g].jacobians)));
  }
  EXPECT_EQ(projected.memo_hits(), 25);
  EXPECT_EQ(projected.computed(), 25);
  // Half remembered, half new: only the new ones are solved, each with its own bits.
  const std::vector<Query> more = RandomQueries(n, 8, 37);
  std::vector<CovarianceProjection::Query> mixed;
  for (size_t g = 0; g < more.size(); ++g) {
    mixed.push_back(queries[g]);
    mixed.push_back({more[g].positions, more[g].jacobians});
  }
  const std::vector<Eigen::Matrix3d> again = projected.ComputeSideBySide(*r, mixed);
  EXPECT_EQ(projected.computed(), 25 + 8);
  for (size_t g = 0; g < mixed.size(); ++g) {
    CovarianceProjection alone;
    EXPECT_TRUE(SameBits(again[g], alone.Compute(*r, mixed[g].positions, mixed[g].jacobians)));
  }
  EXPECT_TRUE(projected.ComputeSideBySide(*r, {}).empty());
  EXPECT_THROW(projected.ComputeSideBySide(
                   *r, {{{2, n}, {Eigen::Matrix3d::Identity(), Eigen::Matrix3d::Identity()}}}),
               std::out_of_range);
  EXPECT_THROW(projected.ComputeSideBySide(*r, {{{2}, {}}}), std::invalid_argument);
  CovarianceProjection alone;
  EXPECT_TRUE(
      SameBits(projected.ComputeSideBySide(
                   *r, {{{7, 60}, {queries[1].jacobians[0], queries[2].jacobians[1]}}})[0],
               alone.Compute(*r, {7, 60}, {queries[1].jacobians[0], queries[2].jacobians[1]})));
}

// ComputeUntil: a test that passes under the zero matrix stops before any row; one that
// never passes gives Compute's bits (and fills the memo); one that passes on the way stops
// with a partial sum that is a lower bound of the result in the positive semidefinite order
// (the exact result minus it has no negative eigenvalue), and the next query is unharmed.
TEST(CovarianceProjectionTest, StoppedSolvesGiveLowerBoundsAndLeaveNoTrace) {
  const int n = 80;
  const auto [r, sigma] = MakeChainWithLoopClosures(n, 35, 29);
  const std::vector<Query> queries = RandomQueries(n, 60, 31);
  CovarianceProjection projected;
  int stopped = 0;
  for (const Query& q : queries) {
    CovarianceProjection fresh;
    const Eigen::Matrix3d exact = fresh.Compute(*r, q.positions, q.jacobians);
    Eigen::Matrix3d result;
    EXPECT_FALSE(projected.ComputeUntil(
        *r, q.positions, q.jacobians, [](const Eigen::Matrix3d&) { return true; }, &result));
    EXPECT_EQ(result, Eigen::Matrix3d::Zero());
    // Stops once the trace passes half the exact one.
    const double half = 0.5 * exact.trace();
    if (!projected.ComputeUntil(
            *r, q.positions, q.jacobians,
            [half](const Eigen::Matrix3d& so_far) { return so_far.trace() >= half; }, &result)) {
      ++stopped;
      EXPECT_GE(result.trace(), half);
      EXPECT_LT(result.trace(), exact.trace());
      const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> rest(exact - result);
      EXPECT_GE(rest.eigenvalues().minCoeff(), -1e-12 * exact.cwiseAbs().maxCoeff());
    } else {
      EXPECT_TRUE(SameBits(result, exact));
    }
    EXPECT_TRUE(projected.ComputeUntil(
        *r, q.positions, q.jacobians, [](const Eigen::Matrix3d&) { return false; }, &result));
    EXPECT_TRUE(SameBits(result, exact));
    EXPECT_TRUE(SameBits(projected.Compute(*r, q.positions, q.jacobians), exact));
  }
  EXPECT_GT(stopped, 20);
  EXPECT_EQ(projected.stopped_early(), 60 + stopped);
  EXPECT_EQ(projected.computed() + projected.memo_hits(), 120 + (60 - stopped));
}

}  // namespace
}  // namespace anchormap
