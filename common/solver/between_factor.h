#pragma once
// Odometry and loop closures inside one trajectory: pose `to` measured in the frame of
// pose `from`. Residual (to (-) from) - z, docs/METHOD.md section 2.

#include <vector>

#include <Eigen/Core>

#include "common/geometry/pose2.h"
#include "common/solver/keys.h"

namespace anchormap {

struct BetweenFactor {
  PoseKey from;
  PoseKey to;
  Pose2 measured_T_from_to;
  Eigen::Matrix3d sqrt_information = Eigen::Matrix3d::Identity();

  std::vector<Key> keys() const { return {from, to}; }
  Eigen::Vector3d Error(const Pose2& T_w_from, const Pose2& T_w_to, Eigen::Matrix3d* J_from,
                        Eigen::Matrix3d* J_to) const {
    return PoseError(Between(T_w_from, T_w_to, J_from, J_to), measured_T_from_to);
  }
  // The same with CosSin::Of(T_w_from.theta()) given.
  Eigen::Vector3d Error(const Pose2& T_w_from, const CosSin& rotation_from, const Pose2& T_w_to,
                        Eigen::Matrix3d* J_from, Eigen::Matrix3d* J_to) const {
    return PoseError(Between(T_w_from, rotation_from, T_w_to, J_from, J_to), measured_T_from_to);
  }
};

}  // namespace anchormap
