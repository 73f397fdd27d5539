#pragma once
// A 2D pose with its time: one sample of a trajectory (estimate or reference). Used by the
// trajectory files and the evaluation tools; times in microseconds like LCM's utime.

#include <cstdint>
#include <vector>

#include "common/geometry/pose2.h"

namespace anchormap {

struct StampedPose2 {
  int64_t utime = 0;  // microseconds
  Pose2 pose;         // frame given by the container (trajectory local frame, world, ...)
};

using StampedTrajectory = std::vector<StampedPose2>;

}  // namespace anchormap
