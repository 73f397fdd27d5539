#pragma once
// Drives a robot along waypoints the simplest collision-free way: turn in place towards
// the next waypoint at the turn rate, then drive straight to it at the speed. The robot
// therefore never leaves the straight legs that the planner checked for clearance.

#include <deque>
#include <string>

#include <Eigen/Core>

#include "common/geometry/pose2.h"
#include "common/util/status.h"

namespace anchormap::sim {

struct MotionOptions {
  double speed_mps = 0.8;        // driving speed
  double turn_rate_radps = 0.8;  // turning speed in place
  double max_dwell_s = 3.0;      // pause at each destination, uniform in [0, max]

  Status Validate() const;  // empty when valid
};

class RouteFollower {
 public:
  RouteFollower(const MotionOptions& options, const Pose2& T_world_body)
      : options_(options), T_world_body_(T_world_body) {}

  // Replaces the remaining route; the robot's current position should be the first point
  // (it is skipped when it coincides with the robot's position).
  void SetRoute(const std::deque<Eigen::Vector2d>& waypoints) { waypoints_ = waypoints; }
  bool Done() const { return waypoints_.empty(); }

  // Moves for `dt_s` seconds along the route and returns the time left over when the
  // route ends before the step does (0 otherwise).
  double Advance(double dt_s);

  const Pose2& pose() const { return T_world_body_; }

 private:
  MotionOptions options_;
  Pose2 T_world_body_;
  std::deque<Eigen::Vector2d> waypoints_;
};

}  // namespace anchormap::sim
