#pragma once
// A dense reference for solver tests: the whitened Jacobian A of a set of factors at given
// values, the dense inverse of A^T A, and a plain dense Gauss-Newton solve. Slow and
// simple on purpose.

#include <map>
#include <vector>

#include <Eigen/Dense>

#include "common/solver/factor.h"

namespace anchormap::testing {

struct KeyLess {
  bool operator()(const Key& a, const Key& b) const {
    return a.trajectory != b.trajectory ? a.trajectory < b.trajectory : a.index < b.index;
  }
};
using Values = std::map<Key, Pose2, KeyLess>;

class DenseOracle {
 public:
  explicit DenseOracle(std::vector<Factor> factors);

  // Whitened Jacobian (rows: 3 per factor; columns: 3 per key in Values order) and the
  // whitened error vector at `values`.
  void Linearize(const Values& values, Eigen::MatrixXd* A, Eigen::VectorXd* b) const;
  // Joint covariance (A^T A)^-1 of `keys` at `values`.
  Eigen::MatrixXd Covariance(const Values& values, const std::vector<Key>& keys) const;
  // Dense Gauss-Newton from `values` until the step is below `tolerance`.
  Values Solve(Values values, double tolerance = 1e-10, int max_iterations = 100) const;
  double Chi2(const Values& values) const;

 private:
  std::vector<Factor> factors_;
};

}  // namespace anchormap::testing
