#include "common/geometry/motion_noise.h"

#include <cmath>

namespace anchormap {

Eigen::Matrix3d MotionNoise::Covariance(const Pose2& motion) const {
  const double distance = motion.translation().norm();
  const double sigma_xy = xy_base_m + xy_per_m * distance;
  const double sigma_theta =
      theta_base_rad + theta_per_rad * std::abs(motion.theta()) + theta_per_m * distance;
  return Eigen::Vector3d(sigma_xy * sigma_xy, sigma_xy * sigma_xy, sigma_theta * sigma_theta)
      .asDiagonal();
}

Status MotionNoise::Validate(const std::string& name, bool positive_base) const {
  const bool finite = std::isfinite(xy_base_m) && std::isfinite(xy_per_m) &&
                      std::isfinite(theta_base_rad) && std::isfinite(theta_per_rad) &&
                      std::isfinite(theta_per_m);
  if (!finite || xy_base_m < 0 || xy_per_m < 0 || theta_base_rad < 0 || theta_per_rad < 0 ||
      theta_per_m < 0) {
    return Status::Error(name + ".* must be finite and >= 0");
  }
  if (positive_base && !(xy_base_m > 0 && theta_base_rad > 0)) {
    return Status::Error(name + ".xy_base_m and " + name +
                         ".theta_base_rad must be > 0 (a covariance must be positive definite "
                         "even for a zero motion)");
  }
  return Status::Ok();
}

}  // namespace anchormap
