#include "server/keyframe_submap.h"

#include <algorithm>

namespace anchormap {

PointCloud KeyframePoints(const TrajectoryRecord& record, int index, double max_range_m) {
  return ScanToPointCloud(record.scans[static_cast<size_t>(index)], max_range_m);
}

SubmapDrawing DrawKeyframeSubmap(const TrajectoryRecord& record, const Smoother& smoother,
                                 PoseKey center, int half_width, double max_range_m) {
  SubmapDrawing drawing;
  drawing.center = center;
  const Pose2 T_local_center = smoother.FramePose(center);
  const int first = std::max(0, center.index - half_width);
  const int last = std::min(record.num_keyframes() - 1, center.index + half_width);
  for (int i = first; i <= last; ++i) {
    const PoseKey key{center.trajectory, i};
    if (!smoother.HasPose(key)) continue;
    drawing.T_center_keyframes.emplace_back(i, Between(T_local_center, smoother.FramePose(key)));
    drawing.num_points += CountScanPoints(record.scans[static_cast<size_t>(i)], max_range_m);
  }
  return drawing;
}

std::unique_ptr<ScanReference> BuildKeyframeSubmap(const TrajectoryRecord& record,
                                                   const SubmapDrawing& drawing, double max_range_m,
                                                   const ScanReferenceOptions& options) {
  if (drawing.num_points == 0) return nullptr;
  std::vector<PointCloud> scans;
  for (const auto& [index, T_center_key] : drawing.T_center_keyframes) {
    scans.push_back(TransformPointCloud(KeyframePoints(record, index, max_range_m), T_center_key));
  }
  return std::make_unique<ScanReference>(scans, options);
}

std::unique_ptr<ScanReference> BuildKeyframeSubmap(const TrajectoryRecord& record,
                                                   const Smoother& smoother, PoseKey center,
                                                   int half_width, double max_range_m,
                                                   const ScanReferenceOptions& options) {
  return BuildKeyframeSubmap(record,
                             DrawKeyframeSubmap(record, smoother, center, half_width, max_range_m),
                             max_range_m, options);
}

}  // namespace anchormap
