#pragma once
// Options of anchormap-agent: one source of defaults (the README table and --help come
// from the registration in agent_main.cc, which points at these fields).

#include <cstdint>
#include <optional>
#include <string>

#include "agent/keyframer.h"
#include "agent/odometry_buffer.h"
#include "common/util/status.h"

namespace anchormap {

// Standard deviations of a keyframe's odometry delta, growing with the motion:
//   sigma_xy    = xy_base_m + xy_per_m * distance
//   sigma_theta = theta_base_rad + theta_per_rad * |angle| + theta_per_m * distance
// The covariance is diagonal in the previous keyframe's frame.
struct OdometryNoiseOptions {
  double xy_base_m = 0.01;
  double xy_per_m = 0.05;  // 5 cm per metre: a typical wheel odometry
  double theta_base_rad = 0.005;
  double theta_per_rad = 0.05;  // 5 % of the turn
  double theta_per_m = 0.02;    // heading drift while driving straight

  Status Validate() const {
    if (!(xy_base_m > 0) || !(theta_base_rad > 0)) {
      return Status::Error(
          "noise.xy_base_m and noise.theta_base_rad must be > 0 (a covariance must be "
          "positive definite even for a zero motion)");
    }
    if (xy_per_m < 0 || theta_per_rad < 0 || theta_per_m < 0) {
      return Status::Error("noise.*_per_* must be >= 0");
    }
    return Status::Ok();
  }
};

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
  OdometryNoiseOptions noise;
  OdometryBufferOptions odometry;

  Status Validate() const {
    if (robot.empty()) return Status::Error("robot must be set");
    for (char c : robot) {
      if (c <= ' ' || c > '~') return Status::Error("robot must be a printable token");
    }
    if (trajectory_id < 0) return Status::Error("trajectory_id must be >= 0");
    if (!(max_range_m > 0)) return Status::Error("max_range_m must be > 0");
    if (max_pending_scans < 1) return Status::Error("max_pending_scans must be >= 1");
    if (Status e = keyframer.Validate(); !e.ok()) return e;
    if (Status e = noise.Validate(); !e.ok()) return e;
    return odometry.Validate();
  }
};

}  // namespace anchormap
