#pragma once
// Options of anchormap-agent: one source of defaults (the README table and --help come
// from the registration in agent_main.cc, which points at these fields).

#include <cstdint>
#include <optional>
#include <string>

#include "agent/keyframer.h"
#include "agent/odometry_buffer.h"
#include "agent/scan_refiner.h"
#include "common/geometry/motion_noise.h"
#include "common/util/status.h"

namespace anchormap {

// The agent's default odometry noise: 5 cm per metre, 5 % of a turn and 0.02 rad per
// metre of heading drift, a typical wheel odometry.
inline MotionNoise DefaultOdometryNoise() {
  MotionNoise noise;
  noise.xy_base_m = 0.01;
  noise.xy_per_m = 0.05;
  noise.theta_base_rad = 0.005;
  noise.theta_per_rad = 0.05;
  noise.theta_per_m = 0.02;
  return noise;
}

struct AgentOptions {
  std::string robot;          // required: upper-case name, e.g. R1
  int64_t trajectory_id = 0;  // 0: drawn at start (DrawTrajectoryId, a fresh session)
  // planar_lidar_t carries no max range: ranges at or beyond this are "no return".
  double max_range_m = 30.0;
  // The laser's mounting pose on the robot body.
  double sensor_x_m = 0.0;
  double sensor_y_m = 0.0;
  double sensor_theta_rad = 0.0;
  // Scans newer than the newest odometry wait here for odometry to catch up.
  int max_pending_scans = 20;
  KeyframerOptions keyframer;
  MotionNoise noise = DefaultOdometryNoise();  // of the odometry between keyframes
  OdometryBufferOptions odometry;
  // Odometry refined by matching each scan against a local map of the last ones (on by default).
  ScanRefinementOptions scan_matching;

  Status Validate() const {
    if (robot.empty()) return Status::Error("robot must be set");
    for (char c : robot) {
      if (c <= ' ' || c > '~') return Status::Error("robot must be a printable token");
    }
    if (trajectory_id < 0) return Status::Error("trajectory_id must be >= 0");
    if (!(max_range_m > 0)) return Status::Error("max_range_m must be > 0");
    if (max_pending_scans < 1) return Status::Error("max_pending_scans must be >= 1");
    if (Status e = keyframer.Validate(); !e.ok()) return e;
    if (Status e = noise.Validate("noise", /*positive_base=*/true); !e.ok()) return e;
    if (Status e = scan_matching.Validate(); !e.ok()) return e;
    return odometry.Validate();
  }
};

}  // namespace anchormap
