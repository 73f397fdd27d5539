#pragma once
// Poses that moved past a tolerance since they were placed (the grid's retrace test,
// KeyframeGrid::Displacement; the map chunks' resend test, MapChunker), found by node
// instead of by a scan of every keyframe.
//
// Every keyframe is a node's pose (+) a fixed offset: with the reduced pose graph an alias
// of a node (pose_aliases.h), otherwise its own variable, the node at the identity. It moves
// only when its node moves, and then by a measure the caller bounds by the node's move:
// translation x translation_scale + rotation x the keyframe's lever (for the grid's
// displacement, translation plus rotation times the scan's reach: the scale 1 and the lever
// the offset's length plus the reach). Each node keeps the pose it was last examined at and
// a margin: the largest measure of its keyframes, from where they were placed, at that pose.
// A node whose margin plus that bound stays below the tolerance (with a relative slack of
// 1e-9, far above round-off) is skipped: none of its keyframes can have moved past it. So a
// pass reads one pose per node plus the keyframes of the nodes that moved, and finds exactly
// what a scan of every keyframe finds (KeyframeMovesTest).

#include <cstdint>
#include <functional>
#include <optional>
#include <unordered_map>
#include <vector>

#include "common/geometry/pose2.h"

namespace anchormap {

class KeyframeMoves {
 public:
  explicit KeyframeMoves(double tolerance, double translation_scale = 1.0)
      : tolerance_(tolerance), translation_scale_(translation_scale) {}
  double tolerance() const { return tolerance_; }

  // Forgets every keyframe and node (the grid's keyframes changed other than by Add).
  void Clear();
  size_t num_keyframes() const { return keyframes_.size(); }
  size_t num_nodes() const { return nodes_.size(); }

  // Keyframe `key` (new here), whose pose is node `node`'s (+) T_node_key (nullopt: the
  // node's pose itself); `lever`: its measure's bound per radian of the node's rotation (see
  // above). `order` sorts the keyframes for the caller. `placed`: it is placed already
  // (after a Clear: its node is examined at the next pass); else the caller places it in the
  // next pass at the pose the pass gives (Pass::inserted). Keyframes are numbered from 0 in
  // the order added since the last Clear (PlacedNow).
  void Add(uint64_t key, uint64_t order, uint64_t node, const std::optional<Pose2>& T_node_key,
           double lever, bool placed);

  struct Found {
    uint64_t key = 0;
    uint64_t order = 0;
    int32_t node = 0;  // this class's, for Settle
    double displacement = 0.0;
    Pose2 pose;  // now
  };
  struct Pass {
    std::vector<Found> inserted;  // added since the last pass, not placed: in order of Add
    std::vector<Found> moved;     // displacement > tolerance, in no particular order
    // With `all`: the examined keyframes within the tolerance (only key and order set).
    std::vector<Found> unchanged;
    int64_t nodes_examined = 0;
  };
  // One pass over the nodes: `node_pose` gives a node's pose now, `displacement` a placed
  // keyframe's (KeyframeGrid::Displacement) at a pose. Every node is examined with `all`.
  // A keyframe's pose is node_pose, or Compose(node_pose, T_node_key) for an offset.
  Pass Examine(
      const std::function<Pose2(uint64_t node)>& node_pose,
      const std::function<std::optional<double>(uint64_t key, const Pose2& pose)>& displacement,
      bool all = false);
  // After the caller placed the pass's keyframes (inserted ones and moved ones at their pose
  // now) except `deferred` (moved ones left for a later pass): those keep their displacement
  // in their node's margin.
  void Settle(const std::vector<Found>& deferred);
  // No pass this time, though keyframes were placed again at poses not given here (the
  // pending ones too): every node is examined at the next pass.
  void Skip();
  // Keyframe `number` placed again at its pose of the last pass (not by Settle: a map
  // chunk sent again with its other keyframes).
  void PlacedNow(int32_t number);

 private:
  struct Node {
    uint64_t id = 0;
    bool examined = false;        // `ref` and `margin` hold
    Pose2 ref;                    // the pose it was last examined at
    double margin = 0.0;          // its keyframes' largest displacement from placed at `ref`
    double lever = 0.0;           // its keyframes' largest offset length plus reach
    double pending_lever = -1.0;  // the same of those added since the last pass; < 0: none
    Pose2 now;                    // at the last pass
    double moved_bound = 0.0;     // the bound's translation part, `ref` to `now`, if skipped
    double rotation = 0.0;        // and its rotation (radians)
    std::vector<int32_t> keyframes;
  };
  struct Keyframe {
    uint64_t key = 0;
    uint64_t order = 0;
    int32_t node = 0;
    bool has_offset = false;
    bool pending = false;  // added, not placed yet
    double lever = 0.0;
    Pose2 T_node_key;
  };
  Pose2 PoseOf(const Keyframe& keyframe, const Pose2& node_pose) const {
    return keyframe.has_offset ? Compose(node_pose, keyframe.T_node_key) : node_pose;
  }

  double tolerance_;
  double translation_scale_;
  std::vector<Node> nodes_;
  std::unordered_map<uint64_t, int32_t> node_index_;
  std::vector<Keyframe> keyframes_;
  std::vector<int32_t> pending_;  // keyframes added since the last pass, in order
};

}  // namespace anchormap
