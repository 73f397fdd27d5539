#pragma once
// How much two keyframes of one trajectory see of the same walls: the share of one scan's
// points, placed at the trajectory's current estimate, that lie near the other scan's points.
// Scan encounters use it to tell two places from one place seen twice (a robot turning
// around, or driving on along one corridor, keeps seeing the same walls): candidates whose
// scans share most of what they see are one piece of evidence, however far apart they are.

#include "common/solver/keys.h"
#include "common/solver/smoother.h"
#include "server/trajectory_table.h"

namespace anchormap {

// The larger of the two shares (i's points near j's, j's points near i's), in [0, 1]: one
// scan that sees a part of what the other sees shares that part. 0 when either keyframe is
// not in the smoother or has no point within max_range_m. Points count as near within
// about distance_m (cells of that size, the 3 x 3 around a point).
double KeyframeOverlap(const TrajectoryRecord& record, const Smoother& smoother, int i, int j,
                       double max_range_m, double distance_m);
// The same for keyframe i of `record_i` and keyframe j of `record_j`, two trajectories of one
// group, each placed at its estimate in the group's frame (0 when they are not in one).
double KeyframeOverlap(const TrajectoryRecord& record_i, int i, const TrajectoryRecord& record_j,
                       int j, const Smoother& smoother, double max_range_m, double distance_m);

}  // namespace anchormap
