#include "server/trajectory_ties.h"

#include <algorithm>
#include <cmath>
#include <functional>
#include <limits>
#include <utility>

namespace anchormap {

int32_t TrajectoryTies::NodeOf(PoseKey key) {
  Tied& tied = ends_[key.trajectory.value()];
  const auto at = std::lower_bound(tied.indices.begin(), tied.indices.end(), key.index);
  const auto position = at - tied.indices.begin();
  if (at != tied.indices.end() && *at == key.index) {
    return tied.nodes[static_cast<size_t>(position)];
  }
  const int32_t node = static_cast<int32_t>(nodes_.size());
  Node added;
  added.key = key;
  if (position > 0) added.below = tied.nodes[static_cast<size_t>(position - 1)];
  if (at != tied.indices.end()) added.above = tied.nodes[static_cast<size_t>(position)];
  if (added.below != kNone) nodes_[static_cast<size_t>(added.below)].above = node;
  if (added.above != kNone) nodes_[static_cast<size_t>(added.above)].below = node;
  nodes_.push_back(std::move(added));
  tied.indices.insert(at, key.index);
  tied.nodes.insert(tied.nodes.begin() + position, node);
  return node;
}

void TrajectoryTies::Add(PoseKey a, PoseKey b) {
  if (a.trajectory == b.trajectory) return;
  const int32_t node_a = NodeOf(a);
  const int32_t node_b = NodeOf(b);
  nodes_[static_cast<size_t>(node_a)].partners.push_back(node_b);
  nodes_[static_cast<size_t>(node_b)].partners.push_back(node_a);
  ++size_;
  const TrajectoryId root = std::min(Root(a.trajectory), Root(b.trajectory));
  // Both ends' trajectories and their old roots point at the joint root (keeps chains short).
  for (const TrajectoryId t :
       {Root(a.trajectory), Root(b.trajectory), a.trajectory, b.trajectory}) {
    if (t != root) parent_[t] = root;
  }
}

void TrajectoryTies::Clear() {
  nodes_.clear();
  ends_.clear();
  parent_.clear();
  size_ = 0;
}

TrajectoryId TrajectoryTies::Root(TrajectoryId trajectory) const {
  // Without path compression (const): a team's few hundred trajectories keep the chains short.
  for (auto up = parent_.find(trajectory); up != parent_.end(); up = parent_.find(trajectory)) {
    trajectory = up->second;
  }
  return trajectory;
}

double TrajectoryTies::DrivenOf(int32_t node, const std::function<double(PoseKey)>& driven) const {
  const Node& n = nodes_[static_cast<size_t>(node)];
  if (std::isnan(n.driven)) n.driven = driven(n.key);
  return n.driven;
}

TrajectoryTies::DriveRange TrajectoryTies::Drive(PoseKey from, PoseKey to,
                                                 const std::function<double(PoseKey)>& driven,
                                                 double limit) const {
  return Search(from, to, driven, limit, /*below=*/false);
}

std::optional<double> TrajectoryTies::ShortestDrive(PoseKey from, PoseKey to,
                                                    const std::function<double(PoseKey)>& driven,
                                                    double limit) const {
  const DriveRange range = Search(from, to, driven, limit, /*below=*/false);
  if (range.at_least != range.at_most || !std::isfinite(range.at_most)) return std::nullopt;
  return range.at_most <= limit ? std::optional<double>(range.at_most) : std::nullopt;
}

bool TrajectoryTies::DriveBelow(PoseKey from, PoseKey to,
                                const std::function<double(PoseKey)>& driven, double limit) const {
  const DriveRange range = Search(from, to, driven, limit, /*below=*/true);
  return range.at_most < limit || range.capped;
}

TrajectoryTies::DriveRange TrajectoryTies::Search(PoseKey from, PoseKey to,
                                                  const std::function<double(PoseKey)>& driven,
                                                  double limit, bool below) const {
  ++stats_.searches;
  const double driven_to = driven(to);
  std::optional<double> best;
  // What the search knows when it stops with nothing shorter than `reached` left to settle.
  const auto known = [&best](double reached, bool capped = false) {
    DriveRange range;
    if (best) range.at_most = *best;
    range.at_least = std::min(reached, range.at_most);
    range.capped = capped && range.at_least < range.at_most;
    return range;
  };
  if (from.trajectory == to.trajectory) best = std::abs(driven(from) - driven_to);
  if (below && best && *best < limit) return known(0.0);
  // Dijkstra over the tied keyframes. Along one trajectory the drive between two keyframes
  // is the difference of the paths driven to them, so each tied keyframe needs edges only to
  // its neighbours by index there (and to `to`, when in its trajectory).
  std::vector<Item>& queue = queue_;
  queue.clear();
  if (settled_in_.size() < nodes_.size()) settled_in_.resize(nodes_.size(), 0);
  if (++search_ == 0) {  // the stamps wrapped: none of them is this search's
    std::fill(settled_in_.begin(), settled_in_.end(), 0);
    search_ = 1;
  }
  // A min-heap on (distance, trajectory, index): a total order, so the nodes come out as they
  // did when the queue held keys (a node settled is not queued again).
  const auto later = [](const Item& a, const Item& b) {
    if (a.distance != b.distance) return a.distance > b.distance;
    if (a.trajectory != b.trajectory) return a.trajectory > b.trajectory;
    return a.index > b.index;
  };
  const auto push = [&](double distance, int32_t node) {
    if (settled_in_[static_cast<size_t>(node)] == search_) return;
    const PoseKey& key = nodes_[static_cast<size_t>(node)].key;
    queue.push_back({distance, key.trajectory.value(), key.index, node});
    std::push_heap(queue.begin(), queue.end(), later);
  };
  // `from` itself may be tied: then it is that node, with its partners. Untied, it is settled
  // first (at 0) and nothing queues it again.
  int32_t start = kNone;
  int32_t start_below = kNone, start_above = kNone;
  if (const auto trajectory = ends_.find(from.trajectory.value()); trajectory != ends_.end()) {
    const std::vector<int32_t>& indices = trajectory->second.indices;
    const auto at = std::lower_bound(indices.begin(), indices.end(), from.index);
    const size_t position = static_cast<size_t>(at - indices.begin());
    if (at != indices.end() && *at == from.index) {
      start = trajectory->second.nodes[position];
    } else {
      if (at != indices.end()) start_above = trajectory->second.nodes[position];
      if (position > 0) start_below = trajectory->second.nodes[position - 1];
    }
  }
  queue.push_back({0.0, from.trajectory.value(), from.index, start});
  int64_t settled = 0;
  while (!queue.empty()) {
    std::pop_heap(queue.begin(), queue.end(), later);
    const Item item = queue.back();
    queue.pop_back();
    const double distance = item.distance;
    if ((best && distance >= *best) || distance > limit) return known(distance);
    double driven_key = 0.0;
    int32_t next_below = kNone, next_above = kNone;
    const Node* node = nullptr;
    if (item.node == kNone) {
      driven_key = driven(from);
      next_below = start_below;
      next_above = start_above;
    } else {
      if (settled_in_[static_cast<size_t>(item.node)] == search_) continue;
      settled_in_[static_cast<size_t>(item.node)] = search_;
      ++stats_.settled;
      stats_.most_settled = std::max(stats_.most_settled, ++settled);
      node = &nodes_[static_cast<size_t>(item.node)];
      driven_key = DrivenOf(item.node, driven);
      next_below = node->below;
      next_above = node->above;
    }
    if (item.trajectory == to.trajectory.value()) {
      const double total = distance + std::abs(driven_key - driven_to);
      if (!best || total < *best) best = total;
      if (below && *best < limit) return known(distance);
    }
    // Its neighbours by index among the trajectory's tied keyframes (the one above first).
    if (next_above != kNone) {
      push(distance + std::abs(driven_key - DrivenOf(next_above, driven)), next_above);
    }
    if (next_below != kNone) {
      push(distance + std::abs(driven_key - DrivenOf(next_below, driven)), next_below);
    }
    if (node == nullptr) continue;
    for (const int32_t partner : node->partners) push(distance, partner);
    if (max_settled_ > 0 && settled >= max_settled_) {
      // The cap: every keyframe still unsettled is at least the queue's least drive away.
      const DriveRange range =
          known(queue.empty() ? std::numeric_limits<double>::infinity() : queue.front().distance,
                /*capped=*/true);
      if (range.capped) ++stats_.capped;
      return range;
    }
  }
  return known(std::numeric_limits<double>::infinity());
}

}  // namespace anchormap
