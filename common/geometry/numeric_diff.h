#pragma once
// Central differences, the reference that analytic Jacobians are tested against.

#include <Eigen/Core>

#include "common/geometry/angle.h"

namespace anchormap {

// Jacobian of f: R^n -> R^3 at x by central differences. The third output component is
// an angle, so its differences are wrapped.
template <typename Function>
Eigen::Matrix<double, 3, Eigen::Dynamic> NumericJacobian(const Function& f,
                                                         const Eigen::VectorXd& x,
                                                         double step = 1e-6) {
  Eigen::Matrix<double, 3, Eigen::Dynamic> jacobian(3, x.size());
  for (int k = 0; k < x.size(); ++k) {
    Eigen::VectorXd plus = x, minus = x;
    plus[k] += step;
    minus[k] -= step;
    Eigen::Vector3d diff = f(plus) - f(minus);
    diff[2] = WrapAngle(diff[2]);
    jacobian.col(k) = diff / (2.0 * step);
  }
  return jacobian;
}

}  // namespace anchormap
