#include "common/geometry/covariance.h"

#include <cmath>

#include <gtest/gtest.h>

namespace anchormap {
namespace {

TEST(CovarianceTest, AcceptsSymmetricPositiveDefinite) {
  Eigen::Matrix3d m;
  m << 4, 1, 0, 1, 3, 0.5, 0, 0.5, 2;
  EXPECT_TRUE(CheckSymmetricPositiveDefinite(m).ok());
}

TEST(CovarianceTest, RejectsBadMatrices) {
  Eigen::Matrix3d asymmetric;
  asymmetric << 1, 0.5, 0, 0, 1, 0, 0, 0, 1;
  EXPECT_EQ(CheckSymmetricPositiveDefinite(asymmetric).message(), "matrix is not symmetric");
  Eigen::Matrix3d indefinite = Eigen::Matrix3d::Identity();
  indefinite(2, 2) = -1;
  EXPECT_EQ(CheckSymmetricPositiveDefinite(indefinite).message(),
            "matrix is not positive definite");
  Eigen::Matrix3d with_nan = Eigen::Matrix3d::Identity();
  with_nan(1, 1) = std::nan("");
  EXPECT_EQ(CheckSymmetricPositiveDefinite(with_nan).message(),
            "matrix has a NaN or infinite entry");
  EXPECT_EQ(CheckSymmetricPositiveDefinite(Eigen::Matrix3d::Zero()).code(),
            ErrorCode::kCovarianceNotSpd);
  EXPECT_EQ(CheckSymmetricPositiveDefinite(with_nan).code(), ErrorCode::kNotFinite);
}

TEST(CovarianceTest, SqrtInformationWhitens) {
  Eigen::Matrix3d covariance;
  covariance << 0.04, 0.01, 0.0, 0.01, 0.09, 0.002, 0.0, 0.002, 0.01;
  const Eigen::Matrix3d S = SqrtInformationFromCovariance(covariance);
  EXPECT_LT((S.transpose() * S - covariance.inverse()).cwiseAbs().maxCoeff(), 1e-9);
  EXPECT_DOUBLE_EQ(S(1, 0), 0.0);  // upper triangular
  EXPECT_DOUBLE_EQ(S(2, 0), 0.0);
  EXPECT_DOUBLE_EQ(S(2, 1), 0.0);
  const double upper[6] = {1, 2, 3, 4, 5, 6};
  const Eigen::Matrix3d info = InformationFromUpperTriangle(upper);
  EXPECT_EQ(info(2, 1), 5);
  EXPECT_EQ(info(1, 2), 5);
}

}  // namespace
}  // namespace anchormap
