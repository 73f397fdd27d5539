#pragma once
// Back to the relations' clock: anchormap-import-carmen --simultaneous shifts each robot's piece
// of a log in time (all pieces start together) and records the shift per robot on
// <R>_CLOCK_SHIFT (common/bus/channels.h). The relations are stamped with the log's own
// clock, so before they are looked up, the estimate's and the odometry's times of each shifted
// robot are moved back: log time = shifted time - shift.

#include <cstdint>
#include <map>
#include <string>

#include "common/types/stamped_pose2.h"
#include "common/util/status.h"
#include "tools/eval/eval_inputs.h"

namespace anchormap {

// The shift of every robot with a <R>_CLOCK_SHIFT message in the LCM log at `path` (none for
// an unshifted log); a robot with two different shifts fails.
Status ReadClockShifts(const std::string& path, std::map<std::string, int64_t>* shift_by_robot);

// Subtracts each robot's shift from the times of its trajectories in `estimate` and of its
// poses in `odometry_by_robot` (may be null). Robots without a shift are left alone.
void ShiftToLogClock(const std::map<std::string, int64_t>& shift_by_robot, MapEstimate* estimate,
                     std::map<std::string, StampedTrajectory>* odometry_by_robot);

}  // namespace anchormap
