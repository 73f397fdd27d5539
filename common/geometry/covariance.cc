#include "common/geometry/covariance.h"

#include <cmath>
#include <sstream>

#include <Eigen/Cholesky>

namespace anchormap {

Status CheckSymmetricPositiveDefinite(const Eigen::Matrix3d& m) {
  if (!m.allFinite()) {
    return Status::Error(ErrorCode::kNotFinite, "matrix has a NaN or infinite entry");
  }
  const double scale = m.cwiseAbs().maxCoeff();
  if ((m - m.transpose()).cwiseAbs().maxCoeff() > 1e-9 * std::max(scale, 1e-300)) {
    return Status::Error(ErrorCode::kCovarianceNotSpd, "matrix is not symmetric");
  }
  Eigen::LLT<Eigen::Matrix3d> llt(0.5 * (m + m.transpose()));
  if (llt.info() != Eigen::Success) {
    return Status::Error(ErrorCode::kCovarianceNotSpd, "matrix is not positive definite");
  }
  const Eigen::Vector3d diagonal = llt.matrixL().toDenseMatrix().diagonal();
  if (diagonal.minCoeff() <= 1e-12 * std::sqrt(scale)) {
    std::ostringstream out;
    out << "matrix is singular to working precision (Cholesky diagonal " << diagonal.transpose()
        << ")";
    return Status::Error(ErrorCode::kCovarianceNotSpd, out.str());
  }
  return Status::Ok();
}

Eigen::Matrix3d SqrtInformationFromInformation(const Eigen::Matrix3d& information) {
  Eigen::LLT<Eigen::Matrix3d> llt(0.5 * (information + information.transpose()));
  // information = L L^T, so S = L^T is upper triangular with S^T S = information.
  return llt.matrixU();
}

Eigen::Matrix3d SqrtInformationFromCovariance(const Eigen::Matrix3d& covariance) {
  return SqrtInformationFromInformation(covariance.inverse());
}

Eigen::Matrix3d InformationFromUpperTriangle(const double upper[6]) {
  Eigen::Matrix3d information;
  information << upper[0], upper[1], upper[2],  //
      upper[1], upper[3], upper[4],             //
      upper[2], upper[4], upper[5];
  return information;
}

}  // namespace anchormap
