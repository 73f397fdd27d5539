#pragma once
// The path each trajectory's odometry drove from its first keyframe to a keyframe (metres,
// nondecreasing in the index: the drive between two keyframes of one trajectory is the
// difference). Extended lazily as the trajectory table's records grow; a function of the
// table, so not in snapshots. Used by the scan sources' drift terms and saturation
// (TrajectoryTies::ShortestDrive's `driven`).

#include <cstdint>
#include <map>
#include <vector>

#include "common/solver/keys.h"
#include "server/trajectory_table.h"

namespace anchormap {

class DrivenPath {
 public:
  // The path to keyframe `index` of `record` (clamped to its keyframes; 0 without any).
  double To(const TrajectoryRecord& record, int32_t index);
  // The path to keyframe `key` of the table's trajectories (0 without its record).
  double To(const TrajectoryTable& table, PoseKey key);

 private:
  std::map<TrajectoryId, std::vector<double>> driven_;
};

}  // namespace anchormap
