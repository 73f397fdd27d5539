#pragma once
// The node rule of a reduced pose graph (Johannsson, Kaess, Fallon & Leonard, "Temporally
// scalable visual SLAM using a reduced pose graph", ICRA 2013), for counting offline what it
// would keep: a keyframe becomes a new node only when no eligible node lies within
// `radius_m` and `angle_rad` of it; otherwise it folds onto the nearest such node (in the
// graph it would add a factor to that node instead of a variable). Eligibility is the
// caller's: the same frame (trajectory group) and, with a world, a line of sight. Used by
// anchormap-bench-reduced-graph; the server does not use it (docs/ARCHITECTURE.md, "Bounding
// the graph by area (rpg23)").

#include <cstdint>
#include <functional>
#include <unordered_map>
#include <vector>

#include "common/geometry/pose2.h"

namespace anchormap {

struct AreaNodeRule {
  double radius_m = 1.0;
  double angle_rad = 0.5;
};

class AreaNodeSelector {
 public:
  struct Node {
    int keyframe = 0;  // the caller's id of the keyframe that made it
    Pose2 pose;
  };
  // True when the keyframe may fold onto `node` (same frame, nothing in between, ...).
  using Eligible = std::function<bool(const Node& node)>;

  explicit AreaNodeSelector(AreaNodeRule rule);

  // Keyframe `keyframe` at `pose` (in the frame it shares with the eligible nodes):
  // returns the index of the nearest eligible node within the rule (by distance, ties to the
  // older node), or -1 after adding the keyframe as a new node. `eligible` may be empty
  // (every node is).
  int Add(int keyframe, const Pose2& pose, const Eligible& eligible = {});

  int num_nodes() const { return static_cast<int>(nodes_.size()); }
  const Node& node(int i) const { return nodes_[static_cast<size_t>(i)]; }

 private:
  int64_t CellKey(int64_t cx, int64_t cy) const {
    // Unsigned shift: negative cells are valid (a left shift of a negative int64_t is UB).
    return static_cast<int64_t>((static_cast<uint64_t>(cx) << 32) ^
                                static_cast<uint64_t>(static_cast<uint32_t>(cy)));
  }

  AreaNodeRule rule_;
  std::vector<Node> nodes_;
  std::unordered_map<int64_t, std::vector<int>> cells_;  // cell of side radius_m -> nodes
};

}  // namespace anchormap
