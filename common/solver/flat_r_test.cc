#include "common/solver/flat_r.h"
#include "common/solver/sparse_r_testing.h"

#include <algorithm>
#include <random>

#include <gtest/gtest.h>
#include <Eigen/Dense>

namespace anchormap {
namespace {

Eigen::MatrixXd Dense(const SparseR& r) {
  Eigen::MatrixXd R = Eigen::MatrixXd::Zero(3 * r.size(), 3 * r.size());
  for (int p = 0; p < r.size(); ++p) {
    R.block<3, 3>(3 * p, 3 * p) = r.row(p).diagonal;
    for (const auto& [q, block] : r.row(p).right) {
      R.block<3, 3>(3 * p, 3 * q) = FlatR::Rounded(block);
    }
  }
  return R;
}

std::vector<Eigen::Vector3d> Split(const Eigen::VectorXd& v) {
  std::vector<Eigen::Vector3d> out(v.size() / 3);
  for (size_t p = 0; p < out.size(); ++p) out[p] = v.segment<3>(3 * p);
  return out;
}

Eigen::VectorXd Join(const std::vector<Eigen::Vector3d>& v) {
  Eigen::VectorXd out(3 * v.size());
  for (size_t p = 0; p < v.size(); ++p) out.segment<3>(3 * p) = v[p];
  return out;
}

// Both solves against dense triangular solves with R (its off-diagonal blocks rounded
// as FlatR keeps them), and R^-T's squared norm.
void ExpectSolvesMatchDense(const FlatR& flat, const SparseR& r, std::mt19937* rng) {
  ASSERT_EQ(flat.size(), r.size());
  const Eigen::MatrixXd R = Dense(r);
  std::normal_distribution<double> g;
  Eigen::VectorXd v(3 * r.size());
  for (int i = 0; i < v.size(); ++i) v(i) = g(*rng);

  std::vector<Eigen::Vector3d> x = Split(v);
  const double norm2 = flat.SolveTransposedInPlace(&x);
  const Eigen::VectorXd y = R.transpose().triangularView<Eigen::Lower>().solve(v);
  EXPECT_LT((Join(x) - y).cwiseAbs().maxCoeff(), 1e-9 * (1 + y.cwiseAbs().maxCoeff()));
  EXPECT_NEAR(norm2, y.squaredNorm(), 1e-9 * y.squaredNorm());

  x = Split(v);
  flat.SolveInPlace(&x);
  const Eigen::VectorXd z = R.triangularView<Eigen::Upper>().solve(v);
  EXPECT_LT((Join(x) - z).cwiseAbs().maxCoeff(), 1e-9 * (1 + z.cwiseAbs().maxCoeff()));
}

TEST(FlatRTest, RefreshCopiesOnlyTheRowsFromTheFirstChangeAndSolvesStayExact) {
  std::mt19937 rng(7);
  constexpr int kChain = 40;
  SparseR r;
  r.Append(kChain);
  for (int p = 0; p < kChain; ++p) r.Eliminate(RandomBetweenRows(p, p - 1, &rng), nullptr);
  FlatR flat;
  EXPECT_EQ(flat.Refresh(r), kChain);
  ExpectSolvesMatchDense(flat, r, &rng);
  EXPECT_EQ(flat.Refresh(r), 0);  // nothing changed

  // A closure from variable 30 to the last one changes rows 30 on only.
  std::vector<int> touched;
  r.Eliminate(RandomBetweenRows(kChain - 1, 30, &rng), &touched);
  EXPECT_EQ(*std::min_element(touched.begin(), touched.end()), 30);
  EXPECT_EQ(flat.Refresh(r), kChain - 30);
  ExpectSolvesMatchDense(flat, r, &rng);

  // New variables: the appended rows, and those a measurement on them changed.
  r.Append(2);
  r.Eliminate(RandomBetweenRows(kChain, kChain - 1, &rng), nullptr);
  r.Eliminate(RandomBetweenRows(kChain + 1, kChain, &rng), nullptr);
  EXPECT_EQ(flat.Refresh(r), 3);
  ExpectSolvesMatchDense(flat, r, &rng);

  // A closure reaching far back changes nearly all of R.
  r.Eliminate(RandomBetweenRows(kChain + 1, 2, &rng), nullptr);
  EXPECT_EQ(flat.Refresh(r), kChain + 2 - 2);
  ExpectSolvesMatchDense(flat, r, &rng);
}

// Bit for bit what a fresh copy's solves give.
void ExpectSolvesEqualAFreshCopy(const FlatR& flat, const SparseR& r, std::mt19937* rng) {
  FlatR fresh;
  fresh.Refresh(r);
  std::normal_distribution<double> g;
  std::vector<Eigen::Vector3d> v(r.size());
  for (Eigen::Vector3d& e : v) e = Eigen::Vector3d(g(*rng), g(*rng), g(*rng));
  std::vector<Eigen::Vector3d> a = v, b = v;
  EXPECT_EQ(flat.SolveTransposedInPlace(&a), fresh.SolveTransposedInPlace(&b));
  flat.SolveInPlace(&a);
  fresh.SolveInPlace(&b);
  for (int p = 0; p < r.size(); ++p) EXPECT_EQ(a[p], b[p]) << "position " << p;
}

// A star (every variable tied to the last one, a hub): a measurement from variable 3 to the
// hub changes rows 3 and the hub's only (the rows between them stay in place); one from 5 to
// 8 fills row 5 with a block at 8, so the unchanged rows 6, 7, 9 and 10 are moved within the
// copy. The solves are a fresh copy's bit for bit either way.
TEST(FlatRTest, UnchangedRowsAfterTheFirstChangeAreMovedWithinTheCopy) {
  std::mt19937 rng(13);
  constexpr int kStar = 12;
  constexpr int kHub = kStar - 1;
  SparseR r;
  r.Append(kStar);
  r.Eliminate(RandomBetweenRows(kHub, -1, &rng), nullptr);
  for (int p = 0; p < kHub; ++p) r.Eliminate(RandomBetweenRows(p, kHub, &rng), nullptr);
  FlatR flat;
  EXPECT_EQ(flat.Refresh(r), kStar);
  ExpectSolvesMatchDense(flat, r, &rng);

  std::vector<int> touched;
  r.Eliminate(RandomBetweenRows(3, kHub, &rng), &touched);
  std::sort(touched.begin(), touched.end());
  EXPECT_EQ(touched, (std::vector<int>{3, kHub}));
  EXPECT_EQ(flat.Refresh(r), kStar - 3);
  ExpectSolvesMatchDense(flat, r, &rng);
  ExpectSolvesEqualAFreshCopy(flat, r, &rng);

  touched.clear();
  std::vector<NewRows> two;
  two.push_back(RandomBetweenRows(5, 8, &rng));
  r.Eliminate(std::move(two), &touched);
  EXPECT_EQ(r.row(5).right.size(), 2u);  // the hub and, new, 8
  EXPECT_EQ(flat.Refresh(r), kStar - 5);
  ExpectSolvesMatchDense(flat, r, &rng);
  ExpectSolvesEqualAFreshCopy(flat, r, &rng);
}

TEST(FlatRTest, ACopyOfRIsCopiedWhole) {
  std::mt19937 rng(11);
  SparseR r;
  r.Append(10);
  for (int p = 0; p < 10; ++p) r.Eliminate(RandomBetweenRows(p, p - 1, &rng), nullptr);
  FlatR flat;
  flat.Refresh(r);
  // A snapshot's R restored in place of the current one: another object, whatever its
  // revisions say.
  SparseR older = r;
  r.Eliminate(RandomBetweenRows(9, 0, &rng), nullptr);
  EXPECT_EQ(flat.Refresh(r), 10);
  EXPECT_EQ(flat.Refresh(older), 10);
  ExpectSolvesMatchDense(flat, older, &rng);
  EXPECT_EQ(flat.Refresh(r), 10);
  ExpectSolvesMatchDense(flat, r, &rng);
}

}  // namespace
}  // namespace anchormap
