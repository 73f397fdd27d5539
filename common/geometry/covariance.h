#pragma once
// 3x3 covariance and information matrices: validation and conversions.

#include <optional>
#include <string>

#include <Eigen/Dense>

namespace anchormap {

// Returns an explanation when `m` is not a finite, symmetric (to a relative 1e-9) and
// positive-definite 3x3 matrix; std::nullopt when it is fine.
std::optional<std::string> CheckSymmetricPositiveDefinite(const Eigen::Matrix3d& m);

// The upper-triangular square root S of information = S^T S, so that the squared
// Mahalanobis norm e^T information e equals |S e|^2 (the "whitening" of ALGORITHM.md 2).
// Preconditions: information is symmetric positive definite.
Eigen::Matrix3d SqrtInformationFromInformation(const Eigen::Matrix3d& information);
Eigen::Matrix3d SqrtInformationFromCovariance(const Eigen::Matrix3d& covariance);

// Information matrix from the upper triangle written row by row (g2o: I11 I12 I13 I22 I23 I33).
Eigen::Matrix3d InformationFromUpperTriangle(const double upper[6]);

}  // namespace anchormap
