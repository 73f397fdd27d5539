#pragma once
// The map test of a first join between two trajectories (issue 11, item 5): with the
// relative pose a candidate measured, the keyframes of each trajectory near its matched place
// are drawn into one frame and each side's end points are tested against the space the other
// side's rays saw free (common/scan_matching/free_space_conflict.h). Pairwise consistency
// cannot refuse a perceptually aliased place whose matches agree with each other through
// odometry (ACES 3 robots simultaneous: two look-alike matches at one T-junction, 10-50 m
// off the truth, agreed); the walls around such a place do not: the wrong map's walls stand
// in the other's open space.

#include <algorithm>
#include <vector>

#include <Eigen/Core>

#include "common/geometry/pose2.h"
#include "common/scan_matching/free_space_conflict.h"
#include "common/solver/keys.h"
#include "common/solver/smoother.h"
#include "server/trajectory_table.h"

namespace anchormap {

// The rays of `record`'s keyframes held by the smoother whose estimates (in the trajectory's
// frame) lie within radius_m of one of `places`, cut at max_range_m, mapped by T_out_frame.
std::vector<RayScan> KeyframeRaysNear(const TrajectoryRecord& record, const Smoother& smoother,
                                      const std::vector<Eigen::Vector2d>& places, double radius_m,
                                      const Pose2& T_out_frame, double max_range_m);

// Both sides of a join drawn in a's frame: a's end points against b's free space and b's
// against a's.
struct JoinConflict {
  FreeSpaceConflict a_in_b;
  FreeSpaceConflict b_in_a;
  // The smaller of the two fractions: in a wrong join each map's walls stand in the other's
  // open space; in a true one a side's far walls, drawn at an estimate that has drifted (or
  // grazed by the other's rays), can conflict alone.
  double fraction() const { return std::min(a_in_b.fraction(), b_in_a.fraction()); }
};
JoinConflict MeasureJoinConflict(const std::vector<RayScan>& a, const std::vector<RayScan>& b,
                                 const FreeSpaceOptions& options);

}  // namespace anchormap
