#include "server/keyframe_overlap.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <unordered_set>

#include "common/scan_matching/point_cloud.h"
#include "server/keyframe_submap.h"
#include "server/relative_pose.h"

namespace anchormap {
namespace {

int64_t CellKey(const Eigen::Vector2d& p, double cell_m) {
  const int64_t ix = static_cast<int64_t>(std::floor(p.x() / cell_m));
  const int64_t iy = static_cast<int64_t>(std::floor(p.y() / cell_m));
  return static_cast<int64_t>((static_cast<uint64_t>(ix) << 32) ^
                              static_cast<uint64_t>(static_cast<uint32_t>(iy)));
}

// The share of `query`'s points with an occupied cell of `cells` in their 3 x 3.
double ShareNear(const PointCloud& query, const std::unordered_set<int64_t>& cells, double cell_m) {
  if (query.empty()) return 0.0;
  int near = 0;
  for (const Eigen::Vector2d& p : query) {
    bool found = false;
    for (int dx = -1; dx <= 1 && !found; ++dx) {
      for (int dy = -1; dy <= 1 && !found; ++dy) {
        found = cells.count(CellKey(p + cell_m * Eigen::Vector2d(dx, dy), cell_m)) > 0;
      }
    }
    near += found ? 1 : 0;
  }
  return static_cast<double>(near) / static_cast<double>(query.size());
}

std::unordered_set<int64_t> Cells(const PointCloud& points, double cell_m) {
  std::unordered_set<int64_t> cells;
  cells.reserve(points.size());
  for (const Eigen::Vector2d& p : points) cells.insert(CellKey(p, cell_m));
  return cells;
}

// Two keyframes' points placed in one frame: the larger share of either near the other's.
double PlacedOverlap(const PointCloud& points_i, const PointCloud& points_j, double distance_m) {
  if (points_i.empty() || points_j.empty()) return 0.0;
  return std::max(ShareNear(points_i, Cells(points_j, distance_m), distance_m),
                  ShareNear(points_j, Cells(points_i, distance_m), distance_m));
}

}  // namespace

double KeyframeOverlap(const TrajectoryRecord& record, const Smoother& smoother, int i, int j,
                       double max_range_m, double distance_m) {
  const PoseKey key_i{record.solver_id, i};
  const PoseKey key_j{record.solver_id, j};
  if (i < 0 || j < 0 || i >= record.num_keyframes() || j >= record.num_keyframes() ||
      !smoother.HasPose(key_i) || !smoother.HasPose(key_j)) {
    return 0.0;
  }
  const PointCloud points_i =
      TransformPointCloud(KeyframePoints(record, i, max_range_m), smoother.FramePose(key_i));
  const PointCloud points_j =
      TransformPointCloud(KeyframePoints(record, j, max_range_m), smoother.FramePose(key_j));
  return PlacedOverlap(points_i, points_j, distance_m);
}

double KeyframeOverlap(const TrajectoryRecord& record_i, int i, const TrajectoryRecord& record_j,
                       int j, const Smoother& smoother, double max_range_m, double distance_m) {
  const PoseKey key_i{record_i.solver_id, i};
  const PoseKey key_j{record_j.solver_id, j};
  if (i < 0 || j < 0 || i >= record_i.num_keyframes() || j >= record_j.num_keyframes() ||
      !smoother.HasPose(key_i) || !smoother.HasPose(key_j) ||
      !InOneFrame(smoother, record_i.solver_id, record_j.solver_id)) {
    return 0.0;
  }
  const PointCloud points_i =
      TransformPointCloud(KeyframePoints(record_i, i, max_range_m), smoother.GlobalPose(key_i));
  const PointCloud points_j =
      TransformPointCloud(KeyframePoints(record_j, j, max_range_m), smoother.GlobalPose(key_j));
  return PlacedOverlap(points_i, points_j, distance_m);
}

}  // namespace anchormap
