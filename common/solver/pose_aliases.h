#pragma once
// Pose aliases: the reduced pose graph's fold (Johannsson, Kaess, Fallon & Leonard, ICRA 2013;
// docs/ARCHITECTURE.md, "Bounding the graph by area"). A keyframe in an already mapped place
// gets no variable of its own: its key is an alias of a node (another key's pose variable,
// possibly of another trajectory of its group) at a fixed offset T_node_key, measured by a
// scan match whose covariance the alias keeps. The smoother answers a pose query on an alias
// as node (+) offset, and maps a measurement on an alias onto the node (MapToNodes), so its
// callers keep naming keyframes.

#include <cstdint>
#include <deque>
#include <unordered_map>
#include <utility>
#include <vector>

#include <Eigen/Core>

#include "common/geometry/pose2.h"
#include "common/solver/keys.h"

namespace anchormap {

// A node made for a keyframe of another trajectory (whose predecessor folded onto a node of
// this one) is a pose of this trajectory, tied to it by a between factor, so that it is
// determined as every pose is (the smoother grounds a new variable through a factor whose
// other variables are known; through an encounter alone it may wait forever once groups
// merge: the 100-robot replay met that). Its index comes from here on: it names no keyframe
// of this trajectory.
constexpr int32_t kBorrowedNodeIndexBase = 1 << 30;

struct PoseAlias {
  PoseKey node;      // a pose variable, never an alias
  Pose2 T_node_key;  // the aliased key's pose in the node's frame
  // Of T_node_key; zero for a keyframe whose node is the variable made for it (a borrowed
  // node: the identity offset, exactly).
  Eigen::Matrix3d covariance = Eigen::Matrix3d::Identity();
  // Folded onto a node made for another keyframe (a scan match put it there); false for a
  // keyframe whose node is the variable borrowed for it.
  bool folded() const { return !covariance.isZero(0.0); }
};

// The aliases by key. Every pose query of the server (the map publication, the sources'
// searches) asks here first, so the lookup is a short per-trajectory array indexed by the
// keyframe index, not a hash of the key (a table of every folded keyframe: 11 % of a
// 20-robot replay's CPU went to its lookups).
class PoseAliases {
 public:
  bool empty() const { return store_.empty(); }
  size_t size() const { return store_.size(); }
  // nullptr when `key` is not an alias.
  const PoseAlias* Find(PoseKey key) const {
    if (store_.empty()) return nullptr;
    const auto it = trajectories_.find(key.trajectory);
    if (it == trajectories_.end()) return nullptr;
    const Slots& slots = it->second;
    if (key.index >= 0 && static_cast<size_t>(key.index) < slots.index.size()) {
      const int64_t slot = slots.index[static_cast<size_t>(key.index)];
      return slot < 0 ? nullptr : &store_[static_cast<size_t>(slot)];
    }
    const auto far = slots.far.find(key.index);
    return far == slots.far.end() ? nullptr : &store_[static_cast<size_t>(far->second)];
  }
  // The caller checked that `key` is new and `alias.node` a variable.
  void Add(PoseKey key, const PoseAlias& alias) {
    Slots& slots = trajectories_[key.trajectory];
    const auto slot = static_cast<int64_t>(store_.size());
    store_.push_back(alias);
    ++slots.count;
    // Keyframe indices come in sequence: the array grows by one. An index far beyond the
    // array (an API caller's own numbering) goes to the map instead of a huge array.
    const auto index = static_cast<size_t>(key.index);
    if (key.index >= 0 && index < 2 * slots.index.size() + kDenseSlack) {
      if (index >= slots.index.size()) slots.index.resize(index + 1, -1);
      slots.index[index] = slot;
    } else {
      slots.far.emplace(key.index, slot);
    }
  }
  // How many of trajectory t's keys are aliases.
  int Count(TrajectoryId t) const {
    const auto it = trajectories_.find(t);
    return it == trajectories_.end() ? 0 : it->second.count;
  }

 private:
  static constexpr size_t kDenseSlack = 1024;
  struct Slots {
    std::vector<int64_t> index;                // keyframe index -> store_ slot, -1: none
    std::unordered_map<int32_t, int64_t> far;  // indices beyond the array
    int count = 0;
  };
  std::deque<PoseAlias> store_;  // a deque: the pointers Find returns stay valid
  std::unordered_map<TrajectoryId, Slots> trajectories_;
};

// A measurement of b in the frame of a, moved onto the variables that hold a and b.
struct NodeMeasurement {
  PoseKey a;
  PoseKey b;
  Pose2 measured_T_a_b;
  Eigen::Matrix3d covariance = Eigen::Matrix3d::Identity();
  bool inside_one_node() const { return a == b; }
};

// z' = T_na_a (+) z (+) T_nb_b^-1 between the nodes (a key that is no alias is its own node),
// its covariance z's propagated plus each offset's propagated and counted twice: an offset's
// error is shared by every measurement mapped through it, and doubling is the bound under
// which two measurements sharing an error are not over-confident (covariance intersection).
// When both keys fold onto one node the result is inside_one_node() (no factor: the
// measurement only says what the offsets already say).
NodeMeasurement MapToNodes(PoseKey a, const PoseAlias* alias_a, PoseKey b, const PoseAlias* alias_b,
                           const Pose2& measured_T_a_b, const Eigen::Matrix3d& covariance);

// d(p^-1)/dp in plain (x, y, theta) coordinates.
Eigen::Matrix3d InverseJacobian(const Pose2& p);

}  // namespace anchormap
