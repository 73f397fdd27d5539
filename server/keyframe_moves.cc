#include "server/keyframe_moves.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include "common/geometry/angle.h"

namespace anchormap {

void KeyframeMoves::Clear() {
  nodes_.clear();
  node_index_.clear();
  keyframes_.clear();
  pending_.clear();
}

void KeyframeMoves::Add(uint64_t key, uint64_t order, uint64_t node,
                        const std::optional<Pose2>& T_node_key, double lever, bool placed) {
  auto [it, is_new] = node_index_.emplace(node, static_cast<int32_t>(nodes_.size()));
  if (is_new) {
    nodes_.emplace_back();
    nodes_.back().id = node;
  }
  Node& n = nodes_[static_cast<size_t>(it->second)];
  Keyframe k;
  k.key = key;
  k.order = order;
  k.node = it->second;
  k.has_offset = T_node_key.has_value();
  if (k.has_offset) k.T_node_key = *T_node_key;
  k.pending = !placed;
  k.lever = lever;
  n.lever = std::max(n.lever, lever);
  const auto index = static_cast<int32_t>(keyframes_.size());
  n.keyframes.push_back(index);
  if (placed) {
    n.examined = false;  // where it was placed is not known here: look at it
  } else {
    n.pending_lever = std::max(n.pending_lever, lever);
    pending_.push_back(index);
  }
  keyframes_.push_back(k);
}

KeyframeMoves::Pass KeyframeMoves::Examine(
    const std::function<Pose2(uint64_t node)>& node_pose,
    const std::function<std::optional<double>(uint64_t key, const Pose2& pose)>& displacement,
    bool all) {
  Pass pass;
  // Skipped only when surely within the tolerance: the bound and the margin carry
  // round-off of ~1e-15 relative, far below this slack.
  const double below = tolerance_ - (1e-9 * tolerance_ + 1e-12);
  for (size_t i = 0; i < nodes_.size(); ++i) {
    Node& n = nodes_[i];
    n.now = node_pose(n.id);
    n.moved_bound = 0.0;
    n.rotation = 0.0;
    if (n.examined) {
      const double translation =
          translation_scale_ * (n.now.translation() - n.ref.translation()).norm();
      const double rotation = std::abs(AngleDifference(n.now.theta(), n.ref.theta()));
      if (!all && n.margin + translation + rotation * n.lever < below) {
        n.moved_bound = translation;
        n.rotation = rotation;
        // Its keyframes added in this pass go in at `now`, not at `ref`: at most this far.
        if (n.pending_lever >= 0.0) {
          n.margin = std::max(n.margin, translation + rotation * n.pending_lever);
        }
        n.pending_lever = -1.0;
        continue;
      }
    }
    ++pass.nodes_examined;
    double margin = 0.0;
    for (const int32_t index : n.keyframes) {
      const Keyframe& k = keyframes_[static_cast<size_t>(index)];
      if (k.pending) continue;  // placed at `now` below: no displacement
      const Pose2 pose = PoseOf(k, n.now);
      const std::optional<double> d = displacement(k.key, pose);
      if (!d) continue;  // not placed: a caller's inconsistency, nothing to move
      if (*d > tolerance_) {
        pass.moved.push_back({k.key, k.order, k.node, *d, pose});
      } else {
        margin = std::max(margin, *d);
        if (all) pass.unchanged.push_back({k.key, k.order, k.node, *d, Pose2()});
      }
    }
    n.examined = true;
    n.ref = n.now;
    n.margin = margin;
    n.pending_lever = -1.0;
  }
  for (const int32_t index : pending_) {
    Keyframe& k = keyframes_[static_cast<size_t>(index)];
    k.pending = false;
    pass.inserted.push_back(
        {k.key, k.order, k.node, 0.0, PoseOf(k, nodes_[static_cast<size_t>(k.node)].now)});
  }
  pending_.clear();
  return pass;
}

void KeyframeMoves::Skip() {
  for (Node& n : nodes_) {
    n.examined = false;
    n.pending_lever = -1.0;
  }
  for (const int32_t index : pending_) keyframes_[static_cast<size_t>(index)].pending = false;
  pending_.clear();
}

void KeyframeMoves::PlacedNow(int32_t number) {
  const Keyframe& k = keyframes_[static_cast<size_t>(number)];
  Node& n = nodes_[static_cast<size_t>(k.node)];
  // An examined node's `ref` is `now`: nothing to add.
  n.margin = std::max(n.margin, n.moved_bound + n.rotation * k.lever);
}

void KeyframeMoves::Settle(const std::vector<Found>& deferred) {
  for (const Found& f : deferred) {
    Node& n = nodes_[static_cast<size_t>(f.node)];
    n.margin = std::max(n.margin, f.displacement);
  }
}

}  // namespace anchormap
