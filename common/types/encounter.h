#pragma once
// A direct encounter: robot `observer` measured robot `observed` at time `utime`
// (anchormap.encounter_t on the bus). A plain value with no LCM.

#include <cstdint>
#include <string>

#include <Eigen/Core>

#include "common/geometry/pose2.h"

namespace anchormap {

struct Encounter {
  int64_t utime = 0;
  std::string observer;
  // The observer's trajectory (session); 0 = unknown (sensors publish 0; the observer's
  // agent fills it in when it relays the encounter to the server).
  int64_t observer_trajectory_id = 0;
  std::string observed;
  // The observed robot's body pose in the observer's body frame, at `utime`.
  Pose2 T_observer_observed;
  Eigen::Matrix3d covariance = Eigen::Matrix3d::Identity();  // (x, y, theta)
  // Relay sequence number within the observer trajectory (0, 1, 2, ..., apart from the
  // keyframes' seq), set by the observer's agent; -1 = none (a sensor's message). The
  // server recognises duplicates and asks for missing ones by it.
  int32_t seq = -1;
};

}  // namespace anchormap
