#include "tests/testing/map_difference.h"

#include <algorithm>
#include <limits>

namespace anchormap::testing {

double LargestPoseDifference(const MergedMap& a, const MergedMap& b) {
  constexpr double kDifferentShape = std::numeric_limits<double>::infinity();
  if (a.trajectories.size() != b.trajectories.size() || a.encounters != b.encounters) {
    return kDifferentShape;
  }
  double largest = 0.0;
  for (size_t t = 0; t < a.trajectories.size(); ++t) {
    const MergedTrajectory& x = a.trajectories[t];
    const MergedTrajectory& y = b.trajectories[t];
    if (x.robot != y.robot || x.trajectory_id != y.trajectory_id || x.anchored != y.anchored ||
        x.pose_utimes != y.pose_utimes || x.poses.size() != y.poses.size()) {
      return kDifferentShape;
    }
    for (size_t i = 0; i < x.poses.size(); ++i) {
      largest = std::max(largest, PoseError(x.poses[i], y.poses[i]).cwiseAbs().maxCoeff());
    }
  }
  return largest;
}

}  // namespace anchormap::testing
