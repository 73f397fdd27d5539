#include "server/trajectory_ties.h"

#include <cmath>
#include <queue>
#include <utility>

namespace anchormap {

void TrajectoryTies::Add(PoseKey a, PoseKey b) {
  if (a.trajectory == b.trajectory) return;
  ends_[a.trajectory][a.index].push_back(b);
  ends_[b.trajectory][b.index].push_back(a);
  ++size_;
}

std::optional<double> TrajectoryTies::ShortestDrive(PoseKey from, PoseKey to,
                                                    const std::function<double(PoseKey)>& driven,
                                                    double limit) const {
  const auto along = [&](PoseKey p, PoseKey q) { return std::abs(driven(p) - driven(q)); };
  std::optional<double> best;
  if (from.trajectory == to.trajectory) best = along(from, to);
  const auto within_limit = [&](std::optional<double> drive) {
    return drive && *drive <= limit ? drive : std::nullopt;
  };
  // Dijkstra over the tied keyframes. Along one trajectory the drive between two keyframes
  // is the difference of the paths driven to them, so each tied keyframe needs edges only to
  // its neighbours by index there (and to `to`, when in its trajectory).
  using Node = std::pair<int64_t, int32_t>;  // (trajectory, index)
  using Item = std::pair<double, Node>;
  std::priority_queue<Item, std::vector<Item>, std::greater<Item>> queue;
  std::map<Node, double> settled;
  const auto push_neighbours_by_index = [&](PoseKey key, double distance) {
    const auto trajectory = ends_.find(key.trajectory);
    if (trajectory == ends_.end()) return;
    const std::map<int32_t, std::vector<PoseKey>>& tied = trajectory->second;
    auto above = tied.upper_bound(key.index);
    if (above != tied.end()) {
      const PoseKey next{key.trajectory, above->first};
      queue.push({distance + along(key, next), {key.trajectory.value(), next.index}});
    }
    auto below = tied.lower_bound(key.index);
    if (below != tied.begin()) {
      --below;
      const PoseKey next{key.trajectory, below->first};
      queue.push({distance + along(key, next), {key.trajectory.value(), next.index}});
    }
  };
  // `from` itself may be tied: then it is a node with its partners.
  queue.push({0.0, {from.trajectory.value(), from.index}});
  while (!queue.empty()) {
    const auto [distance, node] = queue.top();
    queue.pop();
    if ((best && distance >= *best) || distance > limit) break;
    if (!settled.emplace(node, distance).second) continue;
    const PoseKey key{TrajectoryId(node.first), node.second};
    if (key.trajectory == to.trajectory) {
      const double total = distance + along(key, to);
      if (!best || total < *best) best = total;
    }
    push_neighbours_by_index(key, distance);
    const auto trajectory = ends_.find(key.trajectory);
    if (trajectory == ends_.end()) continue;
    const auto here = trajectory->second.find(key.index);
    if (here == trajectory->second.end()) continue;
    for (const PoseKey& other : here->second) {
      queue.push({distance, {other.trajectory.value(), other.index}});
    }
  }
  return within_limit(best);
}

}  // namespace anchormap
