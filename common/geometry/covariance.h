#pragma once
// 3x3 covariance and information matrices: validation and conversions.

#include <Eigen/Dense>

#include "common/util/status.h"

namespace anchormap {

// Ok when `m` is a finite, symmetric (to a relative 1e-9) and positive-definite 3x3
// matrix; otherwise kNotFinite or kCovarianceNotSpd with the explanation.
Status CheckSymmetricPositiveDefinite(const Eigen::Matrix3d& m);

// The upper-triangular square root S of information = S^T S, so that the squared
// Mahalanobis norm e^T information e equals |S e|^2 (the "whitening" of docs/METHOD.md section 2).
// Preconditions: information is symmetric positive definite.
Eigen::Matrix3d SqrtInformationFromInformation(const Eigen::Matrix3d& information);
Eigen::Matrix3d SqrtInformationFromCovariance(const Eigen::Matrix3d& covariance);

// Information matrix from the upper triangle written row by row (g2o: I11 I12 I13 I22 I23 I33).
Eigen::Matrix3d InformationFromUpperTriangle(const double upper[6]);

}  // namespace anchormap
