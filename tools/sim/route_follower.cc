#include "tools/sim/route_follower.h"

#include <algorithm>
#include <cmath>

namespace anchormap::sim {

Status MotionOptions::Validate() const {
  if (!(speed_mps > 0.0 && speed_mps <= 10.0)) return Status::Error("speed must be in (0, 10] m/s");
  if (!(turn_rate_radps > 0.0 && turn_rate_radps <= 10.0))
    return Status::Error("turn rate must be in (0, 10] rad/s");
  if (!(max_dwell_s >= 0.0 && max_dwell_s <= 600.0))
    return Status::Error("dwell must be in [0, 600] s");
  return Status::Ok();
}

double RouteFollower::Advance(double dt_s) {
  constexpr double kArrived = 1e-9;  // metres
  constexpr double kAligned = 1e-9;  // radians
  double left = dt_s;
  while (left > 0.0 && !waypoints_.empty()) {
    const Eigen::Vector2d to_target = waypoints_.front() - T_world_body_.translation();
    const double distance = to_target.norm();
    if (distance < kArrived) {
      waypoints_.pop_front();
      continue;
    }
    const double heading_error =
        AngleDifference(std::atan2(to_target.y(), to_target.x()), T_world_body_.theta());
    if (std::abs(heading_error) > kAligned) {
      const double turn_time = std::abs(heading_error) / options_.turn_rate_radps;
      const double used = std::min(left, turn_time);
      const double turn = used >= turn_time
                              ? heading_error
                              : std::copysign(used * options_.turn_rate_radps, heading_error);
      T_world_body_ = Pose2(T_world_body_.x(), T_world_body_.y(), T_world_body_.theta() + turn);
      left -= used;
      continue;
    }
    const double drive_time = distance / options_.speed_mps;
    if (left >= drive_time) {
      // Snap onto the waypoint exactly so that rounding never accumulates.
      T_world_body_ = Pose2(waypoints_.front().x(), waypoints_.front().y(), T_world_body_.theta());
      waypoints_.pop_front();
      left -= drive_time;
    } else {
      const Eigen::Vector2d step = to_target * (left * options_.speed_mps / distance);
      T_world_body_ =
          Pose2(T_world_body_.x() + step.x(), T_world_body_.y() + step.y(), T_world_body_.theta());
      left = 0.0;
    }
  }
  return left;
}

}  // namespace anchormap::sim
