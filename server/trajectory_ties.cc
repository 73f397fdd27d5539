#include "server/trajectory_ties.h"

#include <algorithm>
#include <cmath>
#include <functional>
#include <utility>

namespace anchormap {

void TrajectoryTies::Add(PoseKey a, PoseKey b) {
  if (a.trajectory == b.trajectory) return;
  for (const auto& [end, partner] : {std::make_pair(a, b), std::make_pair(b, a)}) {
    Tied& tied = ends_[end.trajectory.value()];
    const auto at = std::lower_bound(tied.indices.begin(), tied.indices.end(), end.index);
    const auto position = at - tied.indices.begin();
    if (at == tied.indices.end() || *at != end.index) {
      tied.indices.insert(at, end.index);
      tied.partners.insert(tied.partners.begin() + position, std::vector<PoseKey>());
    }
    tied.partners[static_cast<size_t>(position)].push_back(partner);
  }
  ++size_;
  const TrajectoryId root = std::min(Root(a.trajectory), Root(b.trajectory));
  // Both ends' trajectories and their old roots point at the joint root (keeps chains short).
  for (const TrajectoryId t :
       {Root(a.trajectory), Root(b.trajectory), a.trajectory, b.trajectory}) {
    if (t != root) parent_[t] = root;
  }
}

TrajectoryId TrajectoryTies::Root(TrajectoryId trajectory) const {
  // Without path compression (const): a team's few hundred trajectories keep the chains short.
  for (auto up = parent_.find(trajectory); up != parent_.end(); up = parent_.find(trajectory)) {
    trajectory = up->second;
  }
  return trajectory;
}

bool TrajectoryTies::SettledSet::Insert(uint64_t id) {
  if (2 * (filled_.size() + 1) > slots_.size()) Grow();
  const size_t mask = slots_.size() - 1;
  for (size_t slot = static_cast<size_t>((id * 0x9E3779B97F4A7C15ull) >> shift_);;
       slot = (slot + 1) & mask) {
    if (slots_[slot] == id) return false;
    if (slots_[slot] == kEmpty) {
      slots_[slot] = id;
      filled_.push_back(slot);
      return true;
    }
  }
}

bool TrajectoryTies::SettledSet::Contains(uint64_t id) const {
  if (slots_.empty()) return false;
  const size_t mask = slots_.size() - 1;
  for (size_t slot = static_cast<size_t>((id * 0x9E3779B97F4A7C15ull) >> shift_);;
       slot = (slot + 1) & mask) {
    if (slots_[slot] == id) return true;
    if (slots_[slot] == kEmpty) return false;
  }
}

void TrajectoryTies::SettledSet::Clear() {
  for (size_t slot : filled_) slots_[slot] = kEmpty;
  filled_.clear();
}

void TrajectoryTies::SettledSet::Grow() {
  std::vector<uint64_t> ids;
  ids.reserve(filled_.size());
  for (size_t slot : filled_) ids.push_back(slots_[slot]);
  const size_t capacity = slots_.empty() ? 256 : 2 * slots_.size();
  slots_.assign(capacity, kEmpty);
  shift_ = 64;
  for (size_t c = capacity; c > 1; c >>= 1) --shift_;
  filled_.clear();
  for (uint64_t id : ids) Insert(id);
}

std::optional<double> TrajectoryTies::ShortestDrive(PoseKey from, PoseKey to,
                                                    const std::function<double(PoseKey)>& driven,
                                                    double limit) const {
  const double driven_to = driven(to);
  std::optional<double> best;
  if (from.trajectory == to.trajectory) best = std::abs(driven(from) - driven_to);
  const auto within_limit = [&](std::optional<double> drive) {
    return drive && *drive <= limit ? drive : std::nullopt;
  };
  // Dijkstra over the tied keyframes. Along one trajectory the drive between two keyframes
  // is the difference of the paths driven to them, so each tied keyframe needs edges only to
  // its neighbours by index there (and to `to`, when in its trajectory).
  // A min-heap on (distance, node) (std::priority_queue's operations on a kept vector).
  std::vector<Item>& queue = queue_;
  queue.clear();
  settled_.Clear();
  const std::greater<Item> later;
  // Settled nodes; a node settled is not queued again (the heap's order is total, so the
  // others come out as they would).
  const auto id = [](const Node& node) {
    return (static_cast<uint64_t>(node.first) << 32) ^ static_cast<uint32_t>(node.second);
  };
  const auto push = [&](double distance, const Node& node) {
    if (!settled_.Contains(id(node))) {
      queue.push_back({distance, node});
      std::push_heap(queue.begin(), queue.end(), later);
    }
  };
  // `from` itself may be tied: then it is a node with its partners.
  queue.push_back({0.0, {from.trajectory.value(), from.index}});
  while (!queue.empty()) {
    std::pop_heap(queue.begin(), queue.end(), later);
    const auto [distance, node] = queue.back();
    queue.pop_back();
    if ((best && distance >= *best) || distance > limit) break;
    if (!settled_.Insert(id(node))) continue;
    const PoseKey key{TrajectoryId(node.first), node.second};
    const auto trajectory = ends_.find(node.first);
    const double driven_key = driven(key);
    if (key.trajectory == to.trajectory) {
      const double total = distance + std::abs(driven_key - driven_to);
      if (!best || total < *best) best = total;
    }
    if (trajectory == ends_.end()) continue;
    const std::vector<int32_t>& indices = trajectory->second.indices;
    // Its neighbours by index among the trajectory's tied keyframes (the one above first).
    const auto at = std::lower_bound(indices.begin(), indices.end(), key.index);
    const bool tied_here = at != indices.end() && *at == key.index;
    const auto above = tied_here ? at + 1 : at;
    if (above != indices.end()) {
      const PoseKey next{key.trajectory, *above};
      push(distance + std::abs(driven_key - driven(next)), {node.first, next.index});
    }
    if (at != indices.begin()) {
      const PoseKey next{key.trajectory, *(at - 1)};
      push(distance + std::abs(driven_key - driven(next)), {node.first, next.index});
    }
    if (!tied_here) continue;
    for (const PoseKey& other :
         trajectory->second.partners[static_cast<size_t>(at - indices.begin())]) {
      push(distance, {other.trajectory.value(), other.index});
    }
  }
  return within_limit(best);
}

}  // namespace anchormap
