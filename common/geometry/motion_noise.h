#pragma once
// The uncertainty of a planar motion, growing with its length and turn: the model of the
// agent's odometry constraints and of the server's time corrections of direct encounters.
//   sigma_xy    = xy_base_m + xy_per_m * distance
//   sigma_theta = theta_base_rad + theta_per_rad * |turn| + theta_per_m * distance
// The covariance is diagonal in the frame the motion starts from.

#include <string>

#include <Eigen/Core>

#include "common/geometry/pose2.h"
#include "common/util/status.h"

namespace anchormap {

struct MotionNoise {
  double xy_base_m = 0.0;
  double xy_per_m = 0.0;
  double theta_base_rad = 0.0;
  double theta_per_rad = 0.0;
  double theta_per_m = 0.0;

  // The covariance (x, y, theta) of `motion`.
  Eigen::Matrix3d Covariance(const Pose2& motion) const;
  // Every term >= 0; with `positive_base` the base terms > 0 (so that a zero motion still
  // has a positive-definite covariance). `name` prefixes the messages (e.g. "noise").
  Status Validate(const std::string& name, bool positive_base) const;
};

}  // namespace anchormap
