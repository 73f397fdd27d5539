#include "common/solver/sparse_r.h"
#include "common/solver/sparse_r_testing.h"

#include <algorithm>
#include <limits>
#include <random>

#include <gtest/gtest.h>
#include <Eigen/Dense>

namespace anchormap {
namespace {

Eigen::VectorXd DenseRhs(const SparseR& r) {
  Eigen::VectorXd d(3 * r.size());
  for (int p = 0; p < r.size(); ++p) d.segment<3>(3 * p) = r.row(p).rhs;
  return d;
}

// Random sparse rows over `n` block columns, each touching 1-3 blocks (like factors),
// with the first rows fixing every variable so the system has full rank.
std::vector<NewRows> RandomRows(int n, int extra, std::mt19937* rng) {
  std::normal_distribution<double> g;
  std::vector<NewRows> rows;
  for (int p = 0; p < n; ++p) {
    NewRows row;
    row.blocks.emplace_back(p, Eigen::Matrix3d::Identity() * 3 + 0.3 * Eigen::Matrix3d::Random());
    if (p > 0) row.blocks.emplace_back(p - 1, Eigen::Matrix3d::Random());
    row.rhs = Eigen::Vector3d::Random();
    rows.push_back(row);
  }
  for (int k = 0; k < extra; ++k) {
    NewRows row;
    const int a = std::uniform_int_distribution<int>(0, n - 1)(*rng);
    int b = std::uniform_int_distribution<int>(0, n - 1)(*rng);
    if (b == a) b = (a + 1) % n;
    row.blocks.emplace_back(b, Eigen::Matrix3d::Random());
    row.blocks.emplace_back(a, Eigen::Matrix3d::Random());
    // One draw per statement: a call's argument order is unspecified (gcc's order kept).
    const double rhs2 = g(*rng);
    const double rhs1 = g(*rng);
    const double rhs0 = g(*rng);
    row.rhs = Eigen::Vector3d(rhs0, rhs1, rhs2);
    rows.push_back(row);
  }
  return rows;
}

// A SparseR next to the dense system A x = b of the same measurements, as an oracle.
struct DenseMirror {
  explicit DenseMirror(int n) : A(0, 3 * n), b(0) { r.Append(n); }

  // Appends the measurement's rows to A x = b (blocks of a repeated key add).
  void AppendDense(const NewRows& rows) {
    A.conservativeResize(A.rows() + 3, Eigen::NoChange);
    A.bottomRows(3).setZero();
    for (const auto& [q, m] : rows.blocks) A.block<3, 3>(A.rows() - 3, 3 * q) += m;
    b.conservativeResize(b.size() + 3);
    b.tail(3) = rows.rhs;
  }

  // R is upper triangular and carries the normal equations of A x = b.
  void ExpectSameNormalEquations() const {
    const Eigen::MatrixXd R = DenseR(r);
    EXPECT_EQ(R.triangularView<Eigen::StrictlyLower>().toDenseMatrix().cwiseAbs().maxCoeff(), 0.0);
    EXPECT_LT((R.transpose() * R - A.transpose() * A).cwiseAbs().maxCoeff(), 1e-9);
    EXPECT_LT((R.transpose() * DenseRhs(r) - A.transpose() * b).cwiseAbs().maxCoeff(), 1e-9);
  }

  // The solution equals the dense least-squares solution; the summed leftover its residual.
  void ExpectSolutionAndResidual() const {
    std::vector<Eigen::Vector3d> delta;
    r.BackSubstitute(&delta);
    const Eigen::VectorXd expected = A.colPivHouseholderQr().solve(b);
    for (int p = 0; p < r.size(); ++p) {
      EXPECT_LT((delta[p] - expected.segment<3>(3 * p)).norm(), 1e-9);
    }
    EXPECT_NEAR(leftover, (A * expected - b).squaredNorm(), 1e-9);
  }

  SparseR r;
  Eigen::MatrixXd A;
  Eigen::VectorXd b;
  double leftover = 0.0;
};

TEST(SparseRTest, GivensUpdatesEqualDenseLeastSquaresAfterEveryRow) {
  std::mt19937 rng(11);
  const int n = 12;
  DenseMirror mirror(n);
  for (const NewRows& rows : RandomRows(n, 25, &rng)) {
    mirror.AppendDense(rows);
    std::vector<int> touched;
    mirror.leftover += mirror.r.Eliminate(rows, &touched);
    EXPECT_FALSE(touched.empty());
    mirror.ExpectSameNormalEquations();
  }
  mirror.ExpectSolutionAndResidual();
  EXPECT_EQ(mirror.r.NonZeros(), [&] {
    int64_t nnz = 0;
    for (int p = 0; p < n; ++p) nnz += 6 + 9 * static_cast<int64_t>(mirror.r.row(p).right.size());
    return nnz;
  }());
}

TEST(SparseRTest, SeveralMeasurementsAtOnceEqualDenseLeastSquares) {
  // Groups of 1-4 measurements eliminated together (as one update's), including a repeated
  // key within a measurement and a group whose rows end up entirely absorbed.
  std::mt19937 rng(23);
  const int n = 15;
  DenseMirror mirror(n);
  std::vector<NewRows> all = RandomRows(n, 40, &rng);
  NewRows repeated;
  repeated.blocks.emplace_back(4, Eigen::Matrix3d::Random());
  repeated.blocks.emplace_back(9, Eigen::Matrix3d::Random());
  repeated.blocks.emplace_back(4, Eigen::Matrix3d::Random());
  repeated.rhs = Eigen::Vector3d::Random();
  all.push_back(repeated);
  std::uniform_int_distribution<int> group_size(1, 4);
  int64_t rows_met = 0;
  for (size_t k = 0; k < all.size();) {
    std::vector<NewRows> group;
    for (int g = group_size(rng); g > 0 && k < all.size(); --g) group.push_back(all[k++]);
    for (const NewRows& rows : group) mirror.AppendDense(rows);
    std::vector<int> touched;
    mirror.leftover += mirror.r.Eliminate(std::move(group), &touched);
    rows_met += static_cast<int64_t>(touched.size());
    std::sort(touched.begin(), touched.end());
    EXPECT_EQ(std::adjacent_find(touched.begin(), touched.end()), touched.end())
        << "a block row was visited twice in one call";
    mirror.ExpectSameNormalEquations();
  }
  EXPECT_EQ(mirror.r.eliminated_block_rows(), rows_met);
  mirror.ExpectSolutionAndResidual();
}

TEST(SparseRTest, PartialBackSubstitutionWithZeroThresholdIsExact) {
  std::mt19937 rng(5);
  const int n = 30;
  SparseR r;
  r.Append(n);
  auto rows = RandomRows(n, 40, &rng);
  std::vector<Eigen::Vector3d> full, partial;
  for (size_t k = 0; k < rows.size(); ++k) {
    std::vector<int> touched;
    r.Eliminate(rows[k], &touched);
    if (k + 1 < static_cast<size_t>(n)) continue;  // wait until every variable is determined
    if (partial.empty()) {
      r.BackSubstitute(&partial);
      continue;
    }
    r.BackSubstitutePartial(touched, 0.0, &partial);
    r.BackSubstitute(&full);
    for (int p = 0; p < n; ++p) EXPECT_LT((full[p] - partial[p]).cwiseAbs().maxCoeff(), 1e-12);
  }
  // A large threshold recomputes only the touched rows.
  NewRows last;
  last.blocks.emplace_back(n - 1, Eigen::Matrix3d::Identity());
  std::vector<int> touched;
  r.Eliminate(last, &touched);
  EXPECT_EQ(r.BackSubstitutePartial(touched, 1e9, &partial), 1);
}

TEST(SparseRTest, TailBackSubstitutionIsTheFullSolutionsTailAndLeavesTheRestAlone) {
  std::mt19937 rng(7);
  const int n = 30;
  SparseR r;
  r.Append(n);
  for (const NewRows& row : RandomRows(n, 40, &rng)) {
    std::vector<int> touched;
    r.Eliminate(row, &touched);
  }
  std::vector<Eigen::Vector3d> full;
  r.BackSubstitute(&full);
  for (int from : {0, 12, n - 1}) {
    std::vector<Eigen::Vector3d> tail(n, Eigen::Vector3d::Constant(7.0));
    r.BackSubstituteTail(from, &tail);
    for (int p = 0; p < from; ++p) EXPECT_EQ(tail[p], Eigen::Vector3d::Constant(7.0)) << p;
    for (int p = from; p < n; ++p) EXPECT_EQ(tail[p], full[p]) << p;  // the same operations
  }
}

TEST(SparseRTest, SolveTransposedInvertsRTranspose) {
  std::mt19937 rng(2);
  SparseR r;
  r.Append(8);
  for (const NewRows& rows : RandomRows(8, 10, &rng)) r.Eliminate(rows, nullptr);
  std::vector<RBlockRow> copy;
  for (int p = 0; p < r.size(); ++p) copy.push_back(r.row(p));
  std::vector<Eigen::Vector3d> g(8);
  Eigen::VectorXd gd(24);
  for (int p = 0; p < 8; ++p) {
    g[p] = Eigen::Vector3d::Random();
    gd.segment<3>(3 * p) = g[p];
  }
  const auto y = SolveTransposed(copy, g);
  const Eigen::VectorXd expected = DenseR(r).transpose().triangularView<Eigen::Lower>().solve(gd);
  for (int p = 0; p < 8; ++p) EXPECT_LT((y[p] - expected.segment<3>(3 * p)).norm(), 1e-10);
}

TEST(SparseRTest, EliminationPastItsBudgetLeavesRAsItWas) {
  // A chain, then updates of several measurements (loop closures, some on variables the
  // update appends): with a budget one non-zero below the fill the update adds, or one unit
  // below the work it takes, R stays exactly as it was; with the fill or the work itself, R
  // is what an unbudgeted elimination gives.
  constexpr int64_t kNoBudget = std::numeric_limits<int64_t>::max();
  std::mt19937 rng(5);
  SparseR r;
  r.Append(60);
  r.Eliminate(RandomBetweenRows(0, -1, &rng), nullptr);
  for (int p = 1; p < 60; ++p) r.Eliminate(RandomBetweenRows(p, p - 1, &rng), nullptr);
  auto same = [](const SparseR& a, const SparseR& b) {
    if (a.size() != b.size() || a.NonZeros() != b.NonZeros()) return false;
    for (int p = 0; p < a.size(); ++p) {
      const RBlockRow &x = a.row(p), &y = b.row(p);
      if (x.diagonal != y.diagonal || x.rhs != y.rhs || x.right.size() != y.right.size() ||
          a.RowsReferencing(p) != b.RowsReferencing(p)) {
        return false;
      }
      for (size_t k = 0; k < x.right.size(); ++k) {
        if (x.right[k].first != y.right[k].first || x.right[k].second != y.right[k].second) {
          return false;
        }
      }
    }
    return true;
  };
  int64_t largest_fill = 0;
  for (int update = 0; update < 6; ++update) {
    const int n = r.size();
    std::vector<NewRows> rows;
    rows.push_back(RandomBetweenRows(n, n - 1, &rng));           // a new pose
    rows.push_back(RandomBetweenRows(n + 1, n, &rng));           // and one after it
    rows.push_back(RandomBetweenRows(n + 1, 7 * update, &rng));  // closed on an old one
    std::uniform_int_distribution<int> any(0, n - 1);
    for (int k = 0; k < 2; ++k) {
      const int a = any(rng);
      const int b = any(rng);
      if (a != b) rows.push_back(RandomBetweenRows(a, b, &rng));
    }
    r.Append(2);
    SparseR unbudgeted = r;
    std::vector<int> touched_unbudgeted;
    const double leftover_unbudgeted = unbudgeted.Eliminate(rows, &touched_unbudgeted);
    const int64_t fill = unbudgeted.NonZeros() - r.NonZeros();
    const int64_t work = unbudgeted.eliminated_work() - r.eliminated_work();
    ASSERT_GT(fill, 0);
    ASSERT_GT(work, 0);
    const SparseR before = r;
    std::vector<int> touched;
    double leftover = -1.0;
    {
      SparseR on_work = r;
      EXPECT_FALSE(on_work.EliminateWithin(rows, kNoBudget, work - 1, &touched, &leftover));
      EXPECT_TRUE(same(on_work, before)) << update;
      EXPECT_TRUE(touched.empty());
      EXPECT_EQ(on_work.eliminated_work(), before.eliminated_work());
      EXPECT_TRUE(on_work.EliminateWithin(rows, kNoBudget, work, &touched, &leftover));
      EXPECT_TRUE(same(on_work, unbudgeted)) << update;
      EXPECT_EQ(touched, touched_unbudgeted);
      EXPECT_EQ(leftover, leftover_unbudgeted);
      EXPECT_EQ(on_work.eliminated_work(), unbudgeted.eliminated_work());
      touched.clear();
      leftover = -1.0;
    }
    EXPECT_FALSE(r.EliminateWithin(rows, fill - 1, kNoBudget, &touched, &leftover)) << update;
    EXPECT_TRUE(same(r, before)) << update;
    EXPECT_TRUE(touched.empty());
    EXPECT_EQ(r.eliminated_block_rows(), before.eliminated_block_rows());
    EXPECT_TRUE(r.EliminateWithin(rows, fill, kNoBudget, &touched, &leftover)) << update;
    EXPECT_TRUE(same(r, unbudgeted)) << update;
    EXPECT_EQ(touched, touched_unbudgeted);
    EXPECT_EQ(leftover, leftover_unbudgeted);
    EXPECT_EQ(r.eliminated_block_rows(), unbudgeted.eliminated_block_rows());
    largest_fill = std::max(largest_fill, fill);
  }
  EXPECT_GT(largest_fill, 9 * 20);  // closures on old variables filled rows
}

// The elimination with R's rows copied to and from its work panel by the vector copies
// (AVX-512 where the CPU has it) and by the portable ones: R bit for bit the same, with
// updates of one measurement and of many together (carries merging on their way up R).
TEST(SparseRTest, EveryBuildOfTheRowCopiesGivesTheSameR) {
  std::mt19937 rng(23);
  constexpr int kVars = 40;
  std::vector<NewRows> rows = RandomRows(kVars, 60, &rng);
  SparseR vector_copies, portable_copies;
  vector_copies.Append(kVars);
  portable_copies.Append(kVars);
  for (size_t i = 0; i < rows.size();) {
    const size_t together = i < 60 ? 1 : 5;
    std::vector<NewRows> batch(rows.begin() + i,
                               rows.begin() + std::min(rows.size(), i + together));
    i += together;
    SparseR::VectorCopiesAllowed() = true;
    const double a = vector_copies.Eliminate(batch, nullptr);
    SparseR::VectorCopiesAllowed() = false;
    const double b = portable_copies.Eliminate(batch, nullptr);
    SparseR::VectorCopiesAllowed() = true;
    EXPECT_EQ(a, b);
  }
  for (int p = 0; p < kVars; ++p) {
    const RBlockRow& x = vector_copies.row(p);
    const RBlockRow& y = portable_copies.row(p);
    EXPECT_EQ(x.diagonal, y.diagonal) << "row " << p;
    EXPECT_EQ(x.rhs, y.rhs) << "row " << p;
    ASSERT_EQ(x.right.size(), y.right.size()) << "row " << p;
    for (size_t k = 0; k < x.right.size(); ++k) {
      EXPECT_EQ(x.right[k].first, y.right[k].first);
      EXPECT_EQ(x.right[k].second, y.right[k].second) << "row " << p << " block " << k;
    }
  }
  EXPECT_GT(vector_copies.row(0).right.size(), 2u);  // the closures filled R
}

}  // namespace
}  // namespace anchormap
