#pragma once
// An encounter in the global formulation (the thesis' baseline, docs/METHOD.md section 3):
// both poses live in one shared frame, no anchors. Pose b measured in the frame of pose a.

#include <vector>

#include <Eigen/Core>

#include "common/geometry/pose2.h"
#include "common/solver/keys.h"

namespace anchormap {

struct GlobalEncounterFactor {
  PoseKey a;
  PoseKey b;
  Pose2 measured_T_a_b;
  Eigen::Matrix3d sqrt_information = Eigen::Matrix3d::Identity();

  std::vector<Key> keys() const { return {a, b}; }
  Eigen::Vector3d Error(const Pose2& T_w_a, const Pose2& T_w_b, Eigen::Matrix3d* J_a,
                        Eigen::Matrix3d* J_b) const {
    return PoseError(Between(T_w_a, T_w_b, J_a, J_b), measured_T_a_b);
  }
};

}  // namespace anchormap
