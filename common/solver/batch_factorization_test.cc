#include "common/solver/batch_factorization.h"

#include <dlfcn.h>

#include <algorithm>
#include <random>
#include <string>

#include <gtest/gtest.h>
#include <Eigen/Dense>

namespace anchormap {
namespace {

// Random factors over `n` block positions: a strong unary block on each, plus pairs.
struct RandomSystem {
  std::vector<std::vector<Eigen::Matrix3d>> jacobians;
  std::vector<PositionedFactor> factors;
  Eigen::MatrixXd A;
  Eigen::VectorXd b;
};

RandomSystem MakeSystem(int n, int pairs, std::mt19937* rng) {
  RandomSystem s;
  std::uniform_int_distribution<int> pick(0, n - 1);
  std::vector<std::vector<int>> keys;
  for (int p = 0; p < n; ++p) keys.push_back({p});
  for (int k = 0; k < pairs; ++k) keys.push_back({pick(*rng), pick(*rng)});  // may repeat a key
  s.jacobians.resize(keys.size());
  s.factors.resize(keys.size());
  s.A = Eigen::MatrixXd::Zero(3 * keys.size(), 3 * n);
  s.b = Eigen::VectorXd::Random(3 * keys.size());
  for (size_t f = 0; f < keys.size(); ++f) {
    for (size_t j = 0; j < keys[f].size(); ++j) {
      Eigen::Matrix3d J = Eigen::Matrix3d::Random();
      if (keys[f].size() == 1) J += 4.0 * Eigen::Matrix3d::Identity();
      s.jacobians[f].push_back(J);
      s.A.block<3, 3>(3 * f, 3 * keys[f][j]) += J;
      s.factors[f].positions[j] = keys[f][j];
    }
    s.factors[f].num_keys = static_cast<int>(keys[f].size());
    s.factors[f].jacobians = s.jacobians[f].data();
    s.factors[f].rhs = s.b.segment<3>(3 * f);
  }
  return s;
}

Eigen::MatrixXd Dense(const std::vector<RBlockRow>& rows) {
  const int n = static_cast<int>(rows.size());
  Eigen::MatrixXd R = Eigen::MatrixXd::Zero(3 * n, 3 * n);
  for (int p = 0; p < n; ++p) {
    R.block<3, 3>(3 * p, 3 * p) = rows[p].diagonal;
    for (const auto& [q, block] : rows[p].right) {
      EXPECT_GT(q, p);
      R.block<3, 3>(3 * p, 3 * q) = block;
    }
  }
  return R;
}

TEST(BatchFactorizationTest, SquareRootInformationOfTheNormalEquations) {
  std::mt19937 rng(5);
  const int n = 12;
  RandomSystem s = MakeSystem(n, 25, &rng);
  BatchFactorization batch;
  std::vector<RBlockRow> rows;
  std::string error;
  ASSERT_TRUE(batch.Factor(n, s.factors, &rows, &error)) << error;
  const Eigen::MatrixXd R = Dense(rows);
  const Eigen::MatrixXd AtA = s.A.transpose() * s.A;
  EXPECT_LE((R.transpose() * R - AtA).cwiseAbs().maxCoeff(), 1e-10 * AtA.cwiseAbs().maxCoeff());
  // Upper triangular with a positive diagonal, and R delta = d solves the least squares.
  EXPECT_LE(R.triangularView<Eigen::StrictlyLower>().toDenseMatrix().cwiseAbs().maxCoeff(), 0.0);
  EXPECT_GT(R.diagonal().minCoeff(), 0.0);
  Eigen::VectorXd d(3 * n);
  for (int p = 0; p < n; ++p) d.segment<3>(3 * p) = rows[p].rhs;
  const Eigen::VectorXd delta = R.triangularView<Eigen::Upper>().solve(d);
  const Eigen::VectorXd expected = AtA.ldlt().solve(s.A.transpose() * s.b);
  EXPECT_LE((delta - expected).cwiseAbs().maxCoeff(), 1e-9);
}

// Simplicial (the default switch, on a system this small) and supernodal (switch 0) alike.
TEST(BatchFactorizationTest, UnconstrainedVariableIsAnErrorNamingItsBlock) {
  for (const double supernodal_switch : {BatchFactorization::kSupernodalSwitch, 0.0}) {
    SCOPED_TRACE(supernodal_switch);
    std::mt19937 rng(9);
    const int n = 4;
    RandomSystem s = MakeSystem(n, 0, &rng);
    // Block 2's only factor leaves its heading unconstrained (third Jacobian column zero).
    s.jacobians[2][0].col(2).setZero();
    BatchFactorization batch(supernodal_switch);
    std::vector<RBlockRow> rows;
    std::string error;
    EXPECT_FALSE(batch.Factor(n, s.factors, &rows, &error));
    EXPECT_NE(error.find("not positive definite at scalar column 8 (block 2)"), std::string::npos)
        << error;
  }
}

// Supernodal L L^T and simplicial L D L^T give the same R up to round-off, block pattern
// included: the relaxed supernodes' stored zeros are not blocks of R.
TEST(BatchFactorizationTest, SupernodalGivesTheSimplicialPatternAndValues) {
  std::mt19937 rng(17);
  const int n = 300;
  RandomSystem s = MakeSystem(n, 420, &rng);
  BatchFactorization supernodal(/*supernodal_switch=*/0.0);
  BatchFactorization simplicial(/*supernodal_switch=*/1e30);
  std::vector<RBlockRow> super_rows, simple_rows;
  std::string error;
  ASSERT_TRUE(supernodal.Factor(n, s.factors, &super_rows, &error)) << error;
  ASSERT_TRUE(simplicial.Factor(n, s.factors, &simple_rows, &error)) << error;
  EXPECT_EQ(supernodal.supernodal_factorizations(), 1);
  EXPECT_EQ(simplicial.supernodal_factorizations(), 0);
  size_t blocks = 0;
  double worst = 0.0;
  for (int p = 0; p < n; ++p) {
    const RBlockRow& a = super_rows[p];
    const RBlockRow& b = simple_rows[p];
    ASSERT_EQ(a.right.size(), b.right.size()) << "block row " << p;
    blocks += a.right.size();
    worst = std::max(worst, (a.diagonal - b.diagonal).cwiseAbs().maxCoeff());
    worst = std::max(worst, (a.rhs - b.rhs).cwiseAbs().maxCoeff());
    for (size_t k = 0; k < a.right.size(); ++k) {
      ASSERT_EQ(a.right[k].first, b.right[k].first) << "block row " << p;
      worst = std::max(worst, (a.right[k].second - b.right[k].second).cwiseAbs().maxCoeff());
    }
  }
  EXPECT_GT(blocks, static_cast<size_t>(2 * n));  // fill: not a trivially sparse R
  EXPECT_LE(worst, 1e-9);
}

// The build links the single-threaded OpenBLAS ahead of the machine's libblas.so.3: its
// dgemm_ is the one CHOLMOD's supernodal factorisation calls.
TEST(BatchFactorizationTest, BlasIsTheBuildsSingleThreadedOpenBlas) {
  using GetParallel = int (*)();
  auto* get_parallel = reinterpret_cast<GetParallel>(dlsym(RTLD_DEFAULT, "openblas_get_parallel"));
  ASSERT_NE(get_parallel, nullptr);
  EXPECT_EQ(get_parallel(), 0);  // 0: sequential build
  Dl_info info;
  void* dgemm = dlsym(RTLD_DEFAULT, "dgemm_");
  ASSERT_NE(dgemm, nullptr);
  ASSERT_NE(dladdr(dgemm, &info), 0);
  EXPECT_NE(std::string(info.dli_fname).find("openblas"), std::string::npos) << info.dli_fname;
}

}  // namespace
}  // namespace anchormap
