#pragma once
// Back to the relations' clock: anchormap-import-carmen --simultaneous shifts each robot's piece
// of a log in time (all pieces start together) and records the shift per robot on
// <R>_CLOCK_SHIFT (common/bus/channels.h). The relations are stamped with the log's own
// clock, so before they are looked up, the estimate's and the odometry's times of each shifted
// robot are moved back: log time = shifted time - shift.

#include <cstdint>
#include <map>
#include <string>
#include <vector>

#include "common/types/stamped_pose2.h"
#include "common/util/status.h"
#include "tools/eval/eval_inputs.h"
#include "tools/eval/relations.h"

namespace anchormap {

// The shift of every robot with a <R>_CLOCK_SHIFT message in the LCM log at `path` (none for
// an unshifted log); a robot with two different shifts fails.
Status ReadClockShifts(const std::string& path, std::map<std::string, int64_t>* shift_by_robot);

// Subtracts each robot's shift from the times of its trajectories in `estimate` and of its
// poses in `odometry_by_robot` (may be null). Robots without a shift are left alone.
void ShiftToLogClock(const std::map<std::string, int64_t>& shift_by_robot, MapEstimate* estimate,
                     std::map<std::string, StampedTrajectory>* odometry_by_robot);

// The scans anchormap-import-carmen re-timed because their stamps stepped back in the log
// (<R>_TIME_REPAIR, tools/import_carmen RepairedLaserTimes): the log's stamp -> the repaired
// time, both on the log's clock (each robot's shift taken off). Empty for a log without.
Status ReadTimeRepairs(const std::string& path,
                       const std::map<std::string, int64_t>& shift_by_robot,
                       std::map<int64_t, int64_t>* repaired_by_stamp);

// Moves each relation end stamped exactly (to the microsecond) like a re-timed scan to that
// scan's repaired time; returns how many ends moved.
int64_t ApplyTimeRepairs(const std::map<int64_t, int64_t>& repaired_by_stamp,
                         std::vector<Relation>* relations);

}  // namespace anchormap
