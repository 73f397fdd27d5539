#include "tools/sim/odometry_model.h"

#include <cmath>

namespace anchormap::sim {

Status OdometryNoiseOptions::Validate() const {
  if (!(translation_noise_m_per_sqrt_m >= 0.0 && translation_noise_m_per_sqrt_m < 1.0)) {
    return Status::Error("odometry translation noise must be in [0, 1) m/sqrt(m)");
  }
  if (!(rotation_noise_rad_per_sqrt_m >= 0.0 && rotation_noise_rad_per_sqrt_m < 1.0)) {
    return Status::Error("odometry rotation noise per sqrt(m) must be in [0, 1) rad");
  }
  if (!(rotation_noise_rad_per_sqrt_rad >= 0.0 && rotation_noise_rad_per_sqrt_rad < 1.0)) {
    return Status::Error("odometry rotation noise per sqrt(rad) must be in [0, 1) rad");
  }
  if (!(scale_error_stddev >= 0.0 && scale_error_stddev < 0.2)) {
    return Status::Error("odometry scale error stddev must be in [0, 0.2)");
  }
  return Status::Ok();
}

NoisyOdometry::NoisyOdometry(const OdometryNoiseOptions& options, Rng rng)
    : options_(options), rng_(rng) {
  scale_error_ = rng_.Gaussian(0.0, options_.scale_error_stddev);
}

const Pose2& NoisyOdometry::Integrate(const Pose2& true_increment) {
  const double distance = true_increment.translation().norm();
  const double turned = std::abs(true_increment.theta());
  // Variances add over steps, so the sum over any split of a path has the same spread.
  const double translation_sigma = options_.translation_noise_m_per_sqrt_m * std::sqrt(distance);
  const double rotation_sigma = std::sqrt(
      options_.rotation_noise_rad_per_sqrt_m * options_.rotation_noise_rad_per_sqrt_m * distance +
      options_.rotation_noise_rad_per_sqrt_rad * options_.rotation_noise_rad_per_sqrt_rad * turned);
  // Draw all three every step (even at zero sigma) so the stream stays aligned.
  const double noise_x = rng_.Gaussian() * translation_sigma;
  const double noise_y = rng_.Gaussian() * translation_sigma;
  const double noise_theta = rng_.Gaussian() * rotation_sigma;
  const Pose2 measured((1.0 + scale_error_) * true_increment.x() + noise_x,
                       (1.0 + scale_error_) * true_increment.y() + noise_y,
                       true_increment.theta() + noise_theta);
  T_odom_body_ = Compose(T_odom_body_, measured);
  return T_odom_body_;
}

}  // namespace anchormap::sim
