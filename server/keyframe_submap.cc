#include "server/keyframe_submap.h"

#include <algorithm>

namespace anchormap {

PointCloud KeyframePoints(const TrajectoryRecord& record, int index, double max_range_m) {
  return ScanToPointCloud(record.scans[static_cast<size_t>(index)], max_range_m);
}

std::unique_ptr<ScanReference> BuildKeyframeSubmap(const TrajectoryRecord& record,
                                                   const Smoother& smoother, PoseKey center,
                                                   int half_width, double max_range_m,
                                                   const ScanReferenceOptions& options) {
  const Pose2 T_local_center = smoother.FramePose(center);
  std::vector<PointCloud> scans;
  size_t points = 0;
  const int first = std::max(0, center.index - half_width);
  const int last = std::min(record.num_keyframes() - 1, center.index + half_width);
  for (int i = first; i <= last; ++i) {
    const PoseKey key{center.trajectory, i};
    if (!smoother.HasPose(key)) continue;
    PointCloud cloud = TransformPointCloud(KeyframePoints(record, i, max_range_m),
                                           Between(T_local_center, smoother.FramePose(key)));
    points += cloud.size();
    scans.push_back(std::move(cloud));
  }
  if (points == 0) return nullptr;
  return std::make_unique<ScanReference>(scans, options);
}

}  // namespace anchormap
