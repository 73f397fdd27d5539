#include "server/join_free_space.h"

#include <algorithm>

#include "server/keyframe_submap.h"

namespace anchormap {

std::vector<RayScan> KeyframeRaysNear(const TrajectoryRecord& record, const Smoother& smoother,
                                      const std::vector<Eigen::Vector2d>& places, double radius_m,
                                      const Pose2& T_out_frame, double max_range_m) {
  std::vector<RayScan> rays;
  for (int i = 0; i < record.num_keyframes(); ++i) {
    const PoseKey key{record.solver_id, i};
    if (!smoother.HasPose(key)) continue;
    const Pose2 T_frame_key = smoother.FramePose(key);
    const bool near = std::any_of(places.begin(), places.end(), [&](const Eigen::Vector2d& p) {
      return (T_frame_key.translation() - p).norm() <= radius_m;
    });
    if (!near) continue;
    const Pose2 T_out_key = Compose(T_out_frame, T_frame_key);
    RayScan scan;
    scan.origin =
        T_out_key.TransformPoint(record.scans[static_cast<size_t>(i)].T_body_sensor.translation());
    scan.end_points = TransformPointCloud(KeyframePoints(record, i, max_range_m), T_out_key);
    rays.push_back(std::move(scan));
  }
  return rays;
}

JoinConflict MeasureJoinConflict(const std::vector<RayScan>& a, const std::vector<RayScan>& b,
                                 const FreeSpaceOptions& options) {
  JoinConflict conflict;
  conflict.a_in_b = CountFreeSpaceConflicts(FreeSpaceMap(b, options), a);
  conflict.b_in_a = CountFreeSpaceConflicts(FreeSpaceMap(a, options), b);
  return conflict;
}

JoinConflict MeasureCandidateConflict(const TrajectoryRecord& record_a,
                                      const TrajectoryRecord& record_b, const Smoother& smoother,
                                      PoseKey a, PoseKey b, const Pose2& T_a_b, double radius_m,
                                      double max_range_m, const FreeSpaceOptions& options) {
  const Pose2 T_a_frame_b_frame =
      Compose(Compose(smoother.FramePose(a), T_a_b), smoother.FramePose(b).Inverse());
  return MeasureJoinConflict(
      KeyframeRaysNear(record_a, smoother, {smoother.FramePose(a).translation()}, radius_m, Pose2(),
                       max_range_m),
      KeyframeRaysNear(record_b, smoother, {smoother.FramePose(b).translation()}, radius_m,
                       T_a_frame_b_frame, max_range_m),
      options);
}

}  // namespace anchormap
