#pragma once
// Angles in radians, wrapped to (-pi, pi] (docs/METHOD.md section 1).

#include <cmath>

namespace anchormap {

constexpr double kPi = 3.14159265358979323846;

// Returns `angle` wrapped to (-pi, pi].
inline double WrapAngle(double angle) {
  if (angle > -kPi && angle <= kPi) return angle;
  double wrapped = std::fmod(angle + kPi, 2.0 * kPi);
  if (wrapped <= 0.0) wrapped += 2.0 * kPi;
  return wrapped - kPi;
}

// Returns the signed difference a - b wrapped to (-pi, pi].
inline double AngleDifference(double a, double b) { return WrapAngle(a - b); }

// The yaw of a unit quaternion (w, x, y, z): the heading of its ZYX Euler decomposition,
// exact for a rotation about z only. bot_core.pose_t and TUM files carry quaternions.
inline double YawOfQuaternion(double w, double x, double y, double z) {
  return std::atan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z));
}

// The unit quaternion (w, x, y, z) of a rotation by `yaw` about z.
inline void QuaternionOfYaw(double yaw, double* w, double* x, double* y, double* z) {
  *w = std::cos(yaw / 2.0);
  *x = 0.0;
  *y = 0.0;
  *z = std::sin(yaw / 2.0);
}

}  // namespace anchormap
