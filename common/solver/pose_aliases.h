#pragma once
// Pose aliases: the reduced pose graph's fold (Johannsson, Kaess, Fallon & Leonard, ICRA 2013;
// docs/ARCHITECTURE.md, "Bounding the graph by area"). A keyframe in an already mapped place
// gets no variable of its own: its key is an alias of a node (another key's pose variable,
// possibly of another trajectory of its group) at a fixed offset T_node_key, measured by a
// scan match whose covariance the alias keeps. The smoother answers a pose query on an alias
// as node (+) offset, and maps a measurement on an alias onto the node (MapToNodes), so its
// callers keep naming keyframes.

#include <cstdint>
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
};

class PoseAliases {
 public:
  bool empty() const { return aliases_.empty(); }
  size_t size() const { return aliases_.size(); }
  // nullptr when `key` is not an alias.
  const PoseAlias* Find(PoseKey key) const {
    if (aliases_.empty()) return nullptr;
    const auto it = aliases_.find(Key(key));
    return it == aliases_.end() ? nullptr : &it->second;
  }
  // The caller checked that `key` is new and `alias.node` a variable.
  void Add(PoseKey key, const PoseAlias& alias) {
    aliases_.emplace(Key(key), alias);
    ++per_trajectory_[key.trajectory];
  }
  // How many of trajectory t's keys are aliases.
  int Count(TrajectoryId t) const {
    const auto it = per_trajectory_.find(t);
    return it == per_trajectory_.end() ? 0 : it->second;
  }

 private:
  std::unordered_map<Key, PoseAlias, KeyHash> aliases_;
  std::unordered_map<TrajectoryId, int> per_trajectory_;
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
