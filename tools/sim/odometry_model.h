#pragma once
// Noisy wheel odometry: the true body-frame motion of each odometry step plus random-walk
// noise whose variance grows with the distance driven and the angle turned (so the
// drift does not depend on the odometry rate), and a per-robot scale error drawn once
// (a mis-calibrated wheel radius). Integrated in the robot's own odometry frame, which
// starts at (0, 0, 0) wherever the robot starts in the world.

#include <string>

#include "common/geometry/pose2.h"
#include "common/util/status.h"
#include "tools/sim/random.h"

namespace anchormap::sim {

struct OdometryNoiseOptions {
  // Standard deviation of the translation error (along and across) after 1 m of driving;
  // it grows with the square root of the distance (0.02: 2 cm after 1 m, 20 cm after 100 m).
  double translation_noise_m_per_sqrt_m = 0.02;
  // Heading error after 1 m of driving (1 degree); grows with sqrt(distance).
  double rotation_noise_rad_per_sqrt_m = 0.0174533;
  // Heading error after turning 1 rad in place; grows with sqrt(angle turned).
  double rotation_noise_rad_per_sqrt_rad = 0.01;
  // Standard deviation of the per-robot distance scale error (0.005 = 0.5 %).
  double scale_error_stddev = 0.005;

  Status Validate() const;  // empty when valid
};

class NoisyOdometry {
 public:
  // Draws the robot's scale error from `rng`, then uses it for every step.
  NoisyOdometry(const OdometryNoiseOptions& options, Rng rng);

  // Adds one step: `true_increment` is the true motion in the body frame at the start of
  // the step (Between(T_world_before, T_world_after)). Returns the new odometry pose.
  const Pose2& Integrate(const Pose2& true_increment);

  // T_odom_body: the robot's pose in its odometry frame.
  const Pose2& pose() const { return T_odom_body_; }
  double scale_error() const { return scale_error_; }

 private:
  OdometryNoiseOptions options_;
  Rng rng_;
  double scale_error_ = 0.0;
  Pose2 T_odom_body_;
};

}  // namespace anchormap::sim
