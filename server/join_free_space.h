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
  // Both sides' points together: how much of the two maps, drawn as one, contradicts itself.
  double pooled_fraction() const {
    const size_t seen = a_in_b.seen + b_in_a.seen;
    return seen == 0 ? 0.0
                     : static_cast<double>(a_in_b.contradicts + b_in_a.contradicts) /
                           static_cast<double>(seen);
  }
  // The evidence of the thinner side: its points that landed where the other side saw anything.
  size_t fewer_seen() const { return std::min(a_in_b.seen, b_in_a.seen); }
};
JoinConflict MeasureJoinConflict(const std::vector<RayScan>& a, const std::vector<RayScan>& b,
                                 const FreeSpaceOptions& options);

// One candidate's maps: keyframe b of `record_b` seen from keyframe a of `record_a` at T_a_b;
// each trajectory's keyframes within radius_m of its keyframe (in its own estimate), drawn in
// a's frame, rays cut at max_range_m.
JoinConflict MeasureCandidateConflict(const TrajectoryRecord& record_a,
                                      const TrajectoryRecord& record_b, const Smoother& smoother,
                                      PoseKey a, PoseKey b, const Pose2& T_a_b, double radius_m,
                                      double max_range_m, const FreeSpaceOptions& options);

}  // namespace anchormap
