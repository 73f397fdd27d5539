#include "common/solver/block_givens.h"

#include <random>

#include <gtest/gtest.h>
#include <Eigen/Dense>

namespace anchormap {
namespace {

using WorkSpace = Eigen::Matrix<double, 6, Eigen::Dynamic, Eigen::RowMajor>;

// Rows 0-2: an upper-triangular diagonal block and dense blocks to its right; rows 3-5:
// dense new rows. Both with the layout SparseR::Eliminate uses (rhs in the last column).
WorkSpace RandomWorkSpace(int width, int stride, std::mt19937* rng) {
  std::normal_distribution<double> g;
  WorkSpace W = WorkSpace::Zero(6, stride);
  for (int r = 0; r < 6; ++r) {
    for (int j = (r < 3 ? r : 0); j < width; ++j) W(r, j) = g(*rng);
  }
  return W;
}

TEST(BlockGivensTest, TriangularisesAndPreservesTheNormalEquations) {
  std::mt19937 rng(7);
  for (int width : {4, 7, 10, 31, 163}) {
    const int stride = width + 5;  // the work space is wider than the row being processed
    WorkSpace W = RandomWorkSpace(width, stride, &rng);
    const Eigen::MatrixXd before = W.leftCols(width);
    EliminateBlockRow(W.data(), W.data() + 3 * stride, stride, width);
    const Eigen::MatrixXd after = W.leftCols(width);

    // New rows are zero under the diagonal block, R's diagonal block stays upper triangular.
    EXPECT_EQ(after.block(3, 0, 3, 3).cwiseAbs().maxCoeff(), 0.0) << "width " << width;
    EXPECT_EQ(after(1, 0), 0.0);
    EXPECT_EQ(after(2, 0), 0.0);
    EXPECT_EQ(after(2, 1), 0.0);
    // An orthogonal transformation: [R; N]^T [R; N] (rhs included) is unchanged.
    const Eigen::MatrixXd gram_before = before.transpose() * before;
    const Eigen::MatrixXd gram_after = after.transpose() * after;
    EXPECT_LE((gram_after - gram_before).cwiseAbs().maxCoeff(),
              1e-12 * gram_before.cwiseAbs().maxCoeff())
        << "width " << width;
    // Columns beyond `width` are not touched.
    EXPECT_EQ(W.rightCols(stride - width).cwiseAbs().maxCoeff(), 0.0);
  }
}

TEST(BlockGivensTest, MatchesHouseholderQrUpToRowSigns) {
  // The triangular factor of [R_diag; N] is unique up to the signs of its rows.
  std::mt19937 rng(11);
  const int width = 13;
  WorkSpace W = RandomWorkSpace(width, width, &rng);
  const Eigen::MatrixXd before = W.leftCols(width);
  EliminateBlockRow(W.data(), W.data() + 3 * width, width, width);
  const Eigen::MatrixXd qr = Eigen::HouseholderQR<Eigen::MatrixXd>(before)
                                 .matrixQR()
                                 .topRows(3)
                                 .triangularView<Eigen::Upper>();
  for (int r = 0; r < 3; ++r) {
    const double sign = (W(r, r) > 0) == (qr(r, r) > 0) ? 1.0 : -1.0;
    for (int j = r; j < width; ++j) EXPECT_NEAR(W(r, j), sign * qr(r, j), 1e-12) << r << "," << j;
  }
}

TEST(BlockGivensTest, ZeroEntriesLeaveRowsExactlyUnchanged) {
  // New rows that are already zero under the diagonal: R's row must come out bit-identical.
  std::mt19937 rng(3);
  WorkSpace W = RandomWorkSpace(10, 10, &rng);
  W.block(3, 0, 3, 3).setZero();
  const WorkSpace before = W;
  EliminateBlockRow(W.data(), W.data() + 30, 10, 10);
  EXPECT_EQ((W - before).cwiseAbs().maxCoeff(), 0.0);
}

// The AVX-512 rotations (where the CPU has them) give the AVX2 + FMA build's bits, on
// widths that leave every remainder of eight columns, with zeros where a rotation is (1, 0).
TEST(BlockGivensTest, EveryBuildOfTheRotationsGivesTheSameBits) {
  std::mt19937 rng(5);
  for (int width = 4; width < 60; ++width) {
    for (int trial = 0; trial < 20; ++trial) {
      const int stride = width + 3;
      WorkSpace W = RandomWorkSpace(width, stride, &rng);
      if (trial % 4 == 1) W(4, 1) = 0.0;
      if (trial % 4 == 2) W.block(3, 0, 1, 3).setZero();
      WorkSpace other = W;
      BlockGivensAvx512Allowed() = true;
      EliminateBlockRow(W.data(), W.data() + 3 * stride, stride, width);
      BlockGivensAvx512Allowed() = false;
      EliminateBlockRow(other.data(), other.data() + 3 * stride, stride, width);
      BlockGivensAvx512Allowed() = true;
      for (int r = 0; r < 6; ++r) {
        for (int j = 0; j < stride; ++j) {
          ASSERT_EQ(W(r, j), other(r, j)) << "width " << width << " at " << r << "," << j;
        }
      }
    }
  }
}

}  // namespace
}  // namespace anchormap
