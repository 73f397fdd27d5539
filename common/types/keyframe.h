#pragma once
// A keyframe: what anchormap-agent makes and the server consumes (anchormap.keyframe_t on
// the bus; the codec converts). A plain value with no LCM.

#include <cstdint>
#include <string>

#include <Eigen/Core>

#include "common/geometry/pose2.h"
#include "common/types/laser_scan.h"

namespace anchormap {

struct Keyframe {
  std::string robot;          // e.g. "R1"
  int64_t trajectory_id = 0;  // one value per agent session (a restart is a new trajectory)
  int32_t seq = 0;            // 0, 1, 2, ... within the trajectory
  // Encounters the trajectory's agent relayed before this keyframe (relay seqs below it): a
  // keyframe reveals a lost encounter as it reveals a lost keyframe. Never decreases along
  // a trajectory; 0 reveals nothing (also for keyframes of the older wire layout).
  int32_t encounters_relayed = 0;
  int64_t utime = 0;  // time of the scan, microseconds
  // This keyframe's pose in the trajectory's local (odometry) frame.
  Pose2 T_local_pose;
  // This keyframe in the frame of keyframe seq-1 (identity for seq 0), and its covariance
  // (x, y, theta; identity for seq 0).
  Pose2 T_previous_this;
  Eigen::Matrix3d T_previous_this_covariance = Eigen::Matrix3d::Identity();
  // The scan taken at `utime`; scan.T_body_sensor is the laser's mounting pose.
  LaserScan scan;
};

}  // namespace anchormap
