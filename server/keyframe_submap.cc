#include "server/keyframe_submap.h"

#include <algorithm>
#include <cmath>
#include <tuple>

#include "common/geometry/angle.h"

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

SubmapDrawing DrawKeyframeSubmapNear(const TrajectoryRecord& record, const Smoother& smoother,
                                     PoseKey center, const Eigen::Vector2d& at,
                                     const PlaceSubmapOptions& options, double max_range_m) {
  SubmapDrawing drawing;
  drawing.center = center;
  const Pose2 T_local_center = smoother.FramePose(center);
  // (distance, index, pose in the centre's frame): sorted, ties by index (deterministic).
  std::vector<std::tuple<double, int, Pose2>> near;
  const int last = std::min(record.num_keyframes() - 1, options.last_index);
  for (int i = 0; i <= last; ++i) {
    const PoseKey key{center.trajectory, i};
    if (!smoother.HasPose(key)) continue;
    const Pose2 T_center_key = Between(T_local_center, smoother.FramePose(key));
    const double distance = (T_center_key.translation() - at).norm();
    if (distance <= options.radius_m) near.emplace_back(distance, i, T_center_key);
  }
  std::sort(near.begin(), near.end(), [](const auto& a, const auto& b) {
    return std::get<0>(a) != std::get<0>(b) ? std::get<0>(a) < std::get<0>(b)
                                            : std::get<1>(a) < std::get<1>(b);
  });
  std::vector<bool> kept(static_cast<size_t>(std::max(0, record.num_keyframes())), false);
  for (int i = std::max(0, options.keep_first);
       i <= std::min(record.num_keyframes() - 1, options.keep_last); ++i) {
    const PoseKey key{center.trajectory, i};
    if (!smoother.HasPose(key)) continue;
    drawing.T_center_keyframes.emplace_back(i, Between(T_local_center, smoother.FramePose(key)));
    kept[static_cast<size_t>(i)] = true;
  }
  const size_t limit =
      drawing.T_center_keyframes.size() + static_cast<size_t>(options.max_keyframes);
  for (const auto& [distance, index, pose] : near) {
    if (drawing.T_center_keyframes.size() >= limit) break;
    if (kept[static_cast<size_t>(index)]) continue;
    const bool repeated = std::any_of(
        drawing.T_center_keyframes.begin(), drawing.T_center_keyframes.end(),
        [&, &pose = pose](const std::pair<int, Pose2>& other) {
          return (other.second.translation() - pose.translation()).norm() < options.spacing_m &&
                 std::abs(AngleDifference(other.second.theta(), pose.theta())) <
                     options.spacing_rad;
        });
    if (repeated) continue;
    drawing.T_center_keyframes.emplace_back(index, pose);
  }
  std::sort(drawing.T_center_keyframes.begin(), drawing.T_center_keyframes.end(),
            [](const auto& a, const auto& b) { return a.first < b.first; });
  for (const auto& [index, pose] : drawing.T_center_keyframes) {
    drawing.num_points += CountScanPoints(record.scans[static_cast<size_t>(index)], max_range_m);
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
