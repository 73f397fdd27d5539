#pragma once
// One odometry reading (bot_core.pose_t on the bus): the robot body's pose in its
// odometry frame at a time. A plain value with no LCM.

#include <cstdint>

#include "common/geometry/pose2.h"

namespace anchormap {

struct OdometrySample {
  int64_t utime = 0;
  Pose2 T_odom_body;
};

}  // namespace anchormap
