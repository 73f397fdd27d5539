#include "server/driven_path.h"

#include <algorithm>

namespace anchormap {

double DrivenPath::To(const TrajectoryRecord& record, int32_t index) {
  std::vector<double>& driven = driven_[record.solver_id];
  for (size_t i = driven.size(); i < record.odometry_poses.size(); ++i) {
    driven.push_back(i == 0 ? 0.0
                            : driven.back() + (record.odometry_poses[i].translation() -
                                               record.odometry_poses[i - 1].translation())
                                                  .norm());
  }
  if (driven.empty()) return 0.0;
  return driven[static_cast<size_t>(
      std::clamp<int32_t>(index, 0, static_cast<int32_t>(driven.size()) - 1))];
}

double DrivenPath::To(const TrajectoryTable& table, PoseKey key) {
  const TrajectoryRecord* record = table.FindBySolverId(key.trajectory);
  return record != nullptr ? To(*record, key.index) : 0.0;
}

}  // namespace anchormap
