#pragma once
// A prior on one pose or anchor: the gauge of a trajectory's local frame (its first
// pose) or of an anchor group (its first anchor). docs/METHOD.md sections 2 and 4.

#include <vector>

#include <Eigen/Core>

#include "common/geometry/pose2.h"
#include "common/solver/keys.h"

namespace anchormap {

struct PriorFactor {
  Key key;
  Pose2 prior;
  Eigen::Matrix3d sqrt_information = Eigen::Matrix3d::Identity();

  std::vector<Key> keys() const { return {key}; }
  // e = value - prior (angle wrapped); de/dvalue = I.
  Eigen::Vector3d Error(const Pose2& value, Eigen::Matrix3d* J) const {
    if (J) *J = Eigen::Matrix3d::Identity();
    return PoseError(value, prior);
  }
};

}  // namespace anchormap
