#pragma once
// Angles in radians, wrapped to (-pi, pi] (ALGORITHM.md section 1).

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

}  // namespace anchormap
