#include "tools/sim/robot_sim.h"

#include <deque>

namespace anchormap::sim {

std::string RobotName(int robot_index) { return "R" + std::to_string(robot_index + 1); }

SimRobot::SimRobot(int index, const Pose2& T_world_start, const SimOptions& options)
    : index_(index),
      name_(RobotName(index)),
      motion_(options.motion),
      route_rng_(options.seed, static_cast<uint64_t>(index), RngStream::kRoute),
      follower_(options.motion, T_world_start),
      odometry_(options.odometry,
                Rng(options.seed, static_cast<uint64_t>(index), RngStream::kOdometry)) {}

void SimRobot::PlanNextLeg(const Destinations& destinations, const RoutePlanner& planner) {
  const Eigen::Vector2d here = follower_.pose().translation();
  // A few destinations may be unreachable from here; try others before giving up.
  for (int attempt = 0; attempt < 5; ++attempt) {
    Eigen::Vector2d goal;
    if (!destinations.Next(destinations.HomeRegion(index_), here, route_rng_, &goal)) break;
    const std::vector<Eigen::Vector2d> route = planner.Plan(here, goal);
    if (route.size() >= 2) {
      follower_.SetRoute(std::deque<Eigen::Vector2d>(route.begin(), route.end()));
      ++legs_planned_;
      return;
    }
  }
  ++planning_failures_;
  dwell_left_s_ = 1.0;  // stand still for a second and try again
}

void SimRobot::Advance(double dt_s, const Destinations& destinations, const RoutePlanner& planner) {
  const Pose2 before = follower_.pose();
  double left = dt_s;
  // Each pass consumes time or sets up a route or dwell; planning failures dwell 1 s, so
  // the loop always ends.
  while (left > 1e-12) {
    if (dwell_left_s_ > 0.0) {
      const double used = std::min(left, dwell_left_s_);
      dwell_left_s_ -= used;
      left -= used;
      continue;
    }
    if (follower_.Done()) {
      PlanNextLeg(destinations, planner);
      continue;
    }
    left = follower_.Advance(left);
    if (follower_.Done()) dwell_left_s_ = route_rng_.Uniform(0.0, motion_.max_dwell_s) + 1e-9;
  }
  const Pose2 increment = Between(before, follower_.pose());
  odometry_.Integrate(increment);
  distance_m_ += increment.translation().norm();
  body_velocity_ = increment.vector() / dt_s;
}

}  // namespace anchormap::sim
