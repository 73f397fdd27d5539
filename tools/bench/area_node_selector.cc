#include "tools/bench/area_node_selector.h"

#include <cmath>

#include "common/geometry/angle.h"

namespace anchormap {

AreaNodeSelector::AreaNodeSelector(AreaNodeRule rule) : rule_(rule) {}

int AreaNodeSelector::Add(int keyframe, const Pose2& pose, const Eligible& eligible) {
  const auto cell = [this](double v) {
    return static_cast<int64_t>(std::floor(v / rule_.radius_m));
  };
  const int64_t cx = cell(pose.x()), cy = cell(pose.y());
  int best = -1;
  double best_distance = 0.0;
  // Cells are radius_m wide: every node within radius_m is in the 3 x 3 block around.
  for (int64_t dx = -1; dx <= 1; ++dx) {
    for (int64_t dy = -1; dy <= 1; ++dy) {
      const auto found = cells_.find(CellKey(cx + dx, cy + dy));
      if (found == cells_.end()) continue;
      for (const int i : found->second) {
        const Node& candidate = nodes_[static_cast<size_t>(i)];
        const double distance = (candidate.pose.translation() - pose.translation()).norm();
        if (distance > rule_.radius_m) continue;
        if (std::abs(AngleDifference(candidate.pose.theta(), pose.theta())) > rule_.angle_rad) {
          continue;
        }
        if (best >= 0 && (distance > best_distance || (distance == best_distance && i > best))) {
          continue;
        }
        if (eligible && !eligible(candidate)) continue;
        best = i;
        best_distance = distance;
      }
    }
  }
  if (best >= 0) return best;
  cells_[CellKey(cx, cy)].push_back(num_nodes());
  nodes_.push_back({keyframe, pose});
  return -1;
}

}  // namespace anchormap
