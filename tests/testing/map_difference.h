#pragma once
// How far apart two merged maps are, for tests and benchmarks that compare a restarted or
// replayed server's map with an uninterrupted one's.

#include "common/types/map_outputs.h"

namespace anchormap::testing {

// The largest component of the difference between the two maps' global poses (metres,
// radians); infinity when they do not hold the same trajectories (robot, trajectory id,
// anchored, pose times, pose count, in order) and the same encounter links.
double LargestPoseDifference(const MergedMap& a, const MergedMap& b);

}  // namespace anchormap::testing
