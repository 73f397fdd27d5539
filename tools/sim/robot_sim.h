#pragma once
// One simulated robot: its true pose in the world, its drifting odometry, and the route it
// follows (destination -> plan -> drive -> dwell -> next destination). Each robot draws
// from its own random streams, so robots do not change each other's randomness.

#include <cstdint>
#include <string>

#include "common/geometry/pose2.h"
#include "tools/sim/destinations.h"
#include "tools/sim/odometry_model.h"
#include "tools/sim/route_follower.h"
#include "tools/sim/route_planner.h"
#include "tools/sim/sim_options.h"

namespace anchormap::sim {

// "R1", "R2", ... for robot index 0, 1, ...
std::string RobotName(int robot_index);

class SimRobot {
 public:
  SimRobot(int index, const Pose2& T_world_start, const SimOptions& options);

  // Moves for `dt_s` seconds (driving, turning, dwelling, planning the next leg when a
  // destination is reached) and integrates the odometry over the step.
  void Advance(double dt_s, const Destinations& destinations, const RoutePlanner& planner);

  int index() const { return index_; }
  const std::string& name() const { return name_; }
  // True pose in the world frame.
  const Pose2& T_world_body() const { return follower_.pose(); }
  // Odometry pose in the robot's own odometry frame (identity at the start).
  const Pose2& T_odom_body() const { return odometry_.pose(); }
  // Body-frame velocities over the last step: forward (m/s), lateral, yaw rate (rad/s).
  const Eigen::Vector3d& body_velocity() const { return body_velocity_; }
  double distance_m() const { return distance_m_; }
  int legs_planned() const { return legs_planned_; }
  int planning_failures() const { return planning_failures_; }

 private:
  void PlanNextLeg(const Destinations& destinations, const RoutePlanner& planner);

  int index_;
  std::string name_;
  MotionOptions motion_;
  Rng route_rng_;
  RouteFollower follower_;
  NoisyOdometry odometry_;
  double dwell_left_s_ = 0.0;
  Eigen::Vector3d body_velocity_ = Eigen::Vector3d::Zero();
  double distance_m_ = 0.0;
  int legs_planned_ = 0;
  int planning_failures_ = 0;
};

}  // namespace anchormap::sim
