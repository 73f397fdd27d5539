#include "common/solver/flat_r.h"
#include "common/solver/sparse_r_testing.h"

#include <algorithm>
#include <array>
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

// The plain scalar solves FlatR's builds must reproduce bit for bit: blocks rounded to
// float, diagonal blocks inverted, each entry's products summed in the documented order.
std::array<double, 6> InverseUpper(const Eigen::Matrix3d& d) {
  const double i00 = 1.0 / d(0, 0), i11 = 1.0 / d(1, 1), i22 = 1.0 / d(2, 2);
  const double i01 = -d(0, 1) * i00 * i11;
  const double i12 = -d(1, 2) * i11 * i22;
  const double i02 = -(d(0, 1) * i12 + d(0, 2) * i22) * i00;
  return {i00, i01, i02, i11, i12, i22};
}

double PlainSolveTransposed(const SparseR& r, std::vector<Eigen::Vector3d>* x) {
  double norm2 = 0.0;
  for (int p = 0; p < r.size(); ++p) {
    const std::array<double, 6> i = InverseUpper(r.row(p).diagonal);
    const Eigen::Vector3d xp = (*x)[p];
    const double y0 = i[0] * xp[0];
    const double y1 = i[1] * xp[0] + i[3] * xp[1];
    const double y2 = i[2] * xp[0] + i[4] * xp[1] + i[5] * xp[2];
    (*x)[p] = Eigen::Vector3d(y0, y1, y2);
    for (const auto& [q, block] : r.row(p).right) {
      const Eigen::Matrix3d b = FlatR::Rounded(block);
      for (int j = 0; j < 3; ++j) (*x)[q][j] -= (b(0, j) * y0 + b(1, j) * y1) + b(2, j) * y2;
    }
    norm2 += y0 * y0 + y1 * y1 + y2 * y2;
  }
  return norm2;
}

void PlainSolve(const SparseR& r, std::vector<Eigen::Vector3d>* x) {
  for (int p = r.size() - 1; p >= 0; --p) {
    double s[3] = {(*x)[p][0], (*x)[p][1], (*x)[p][2]};
    for (const auto& [q, block] : r.row(p).right) {
      const Eigen::Matrix3d b = FlatR::Rounded(block);
      const Eigen::Vector3d& xq = (*x)[q];
      for (int i = 0; i < 3; ++i) s[i] -= (b(i, 0) * xq[0] + b(i, 1) * xq[1]) + b(i, 2) * xq[2];
    }
    const std::array<double, 6> i = InverseUpper(r.row(p).diagonal);
    (*x)[p] = Eigen::Vector3d(i[0] * s[0] + i[1] * s[1] + i[2] * s[2], i[3] * s[1] + i[4] * s[2],
                              i[5] * s[2]);
  }
}

// The vector builds (AVX2 where the CPU has it) and the portable one give the plain solves'
// bits, on an R with rows of 0 to 9 off-diagonal blocks (a chain and closures to far back),
// refreshed after each change.
TEST(FlatRTest, EveryBuildOfTheSolvesGivesThePlainSolvesBits) {
  std::mt19937 rng(17);
  constexpr int kChain = 60;
  SparseR r;
  r.Append(kChain);
  for (int p = 0; p < kChain; ++p) r.Eliminate(RandomBetweenRows(p, p - 1, &rng), nullptr);
  FlatR flat;
  std::normal_distribution<double> g;
  for (int round = 0; round < 12; ++round) {
    std::uniform_int_distribution<int> pick(0, kChain - 2);
    const int from = pick(rng);
    r.Eliminate(RandomBetweenRows(kChain - 1 - round % 5, from, &rng), nullptr);
    flat.Refresh(r);
    std::vector<Eigen::Vector3d> v(r.size());
    for (Eigen::Vector3d& e : v) e = Eigen::Vector3d(g(rng), g(rng), g(rng));
    std::vector<Eigen::Vector3d> plain = v;
    const double plain_norm2 = PlainSolveTransposed(r, &plain);
    std::vector<Eigen::Vector3d> back = plain;
    PlainSolve(r, &back);
    for (const bool vector_solves : {true, false}) {
      FlatR::VectorSolvesAllowed() = vector_solves;
      std::vector<Eigen::Vector3d> y;  // out of place: v is left as it was
      EXPECT_EQ(flat.SolveTransposed(v, &y), plain_norm2);
      for (int p = 0; p < r.size(); ++p) ASSERT_EQ(y[p], plain[p]) << "position " << p;
      std::vector<Eigen::Vector3d> x = v;
      EXPECT_EQ(flat.SolveTransposedInPlace(&x), plain_norm2);
      for (int p = 0; p < r.size(); ++p) ASSERT_EQ(x[p], plain[p]) << "position " << p;
      flat.SolveInPlace(&x);
      for (int p = 0; p < r.size(); ++p) ASSERT_EQ(x[p], back[p]) << "position " << p;
    }
    FlatR::VectorSolvesAllowed() = true;
  }
}

}  // namespace
}  // namespace anchormap
