#include "common/solver/pose_aliases.h"

#include <cmath>

namespace anchormap {

Eigen::Matrix3d InverseJacobian(const Pose2& p) {
  const double c = std::cos(p.theta()), s = std::sin(p.theta());
  Eigen::Matrix3d J;
  J << -c, -s, s * p.x() - c * p.y(),  //
      s, -c, c * p.x() + s * p.y(),    //
      0.0, 0.0, -1.0;
  return J;
}

NodeMeasurement MapToNodes(PoseKey a, const PoseAlias* alias_a, PoseKey b, const PoseAlias* alias_b,
                           const Pose2& measured_T_a_b, const Eigen::Matrix3d& covariance) {
  NodeMeasurement out;
  out.a = alias_a != nullptr ? alias_a->node : a;
  out.b = alias_b != nullptr ? alias_b->node : b;
  const Pose2 T_na_a = alias_a != nullptr ? alias_a->T_node_key : Pose2();
  const Pose2 T_b_nb = alias_b != nullptr ? alias_b->T_node_key.Inverse() : Pose2();
  Eigen::Matrix3d J_offset_a, J_z, J_first, J_inverse_b;
  const Pose2 first = Compose(T_na_a, measured_T_a_b, &J_offset_a, &J_z);
  out.measured_T_a_b = Compose(first, T_b_nb, &J_first, &J_inverse_b);
  const Eigen::Matrix3d J_measured = J_first * J_z;
  out.covariance = J_measured * covariance * J_measured.transpose();
  if (alias_a != nullptr) {
    const Eigen::Matrix3d J = J_first * J_offset_a;
    out.covariance += 2.0 * J * alias_a->covariance * J.transpose();
  }
  if (alias_b != nullptr) {
    const Eigen::Matrix3d J = J_inverse_b * InverseJacobian(alias_b->T_node_key);
    out.covariance += 2.0 * J * alias_b->covariance * J.transpose();
  }
  out.covariance = 0.5 * (out.covariance + out.covariance.transpose());
  return out;
}

}  // namespace anchormap
