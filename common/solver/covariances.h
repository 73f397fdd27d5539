#pragma once
// Covariance recovery from the square-root information matrix (Kaess & Dellaert, RAS
// 2009; docs/METHOD.md section 6), by 3x3 blocks. With Sigma = (R^T R)^-1 and R Sigma =
// R^-T (block lower triangular, diagonal blocks R_ii^-T):
//
//   Sigma_ll = R_ll^-1 ( R_ll^-T - sum_{j>l, R_lj != 0} R_lj Sigma_jl )
//   Sigma_il = -R_ii^-1 sum_{j>i, R_ij != 0} R_ij Sigma_jl              (i < l)
//
// Only the entries a query needs are computed, and memoised. Entries outside R's
// pattern work too, at a higher cost. The object holds its own reference to R, so a
// snapshot can be queried off the solver's thread while the solver moves on.

#include <cstdint>
#include <memory>
#include <unordered_map>
#include <vector>

#include <Eigen/Core>

#include "common/solver/sparse_r.h"

namespace anchormap {

class CovarianceRecovery {
 public:
  explicit CovarianceRecovery(std::shared_ptr<const SparseR> r) : r_(std::move(r)) {}

  // Sigma_il, the 3x3 covariance block between positions i and l.
  Eigen::Matrix3d Block(int i, int l);
  // The joint covariance of several positions, blocks in the order given.
  Eigen::MatrixXd Joint(const std::vector<int>& positions);
  // Entries computed so far (memoised).
  size_t memoised() const { return memo_.size(); }

 private:
  // Computes the canonical entry (i <= l) and everything it depends on.
  const Eigen::Matrix3d& Canonical(int i, int l);
  const Eigen::Matrix3d* Find(int i, int l) const;
  uint64_t Id(int i, int l) const {
    return static_cast<uint64_t>(i) * static_cast<uint64_t>(r_->size()) + static_cast<uint64_t>(l);
  }

  std::shared_ptr<const SparseR> r_;
  std::unordered_map<uint64_t, Eigen::Matrix3d> memo_;
};

}  // namespace anchormap
