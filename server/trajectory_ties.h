#pragma once
// The constraints that tie one trajectory to another (encounters of every kind), kept by the
// server as they enter the graph. A near search between joined trajectories asks how far the
// two robots drove since the nearest tie: the estimate of two trajectories is exact where a
// constraint ties them and drifts apart with the path driven away from it, in both (or
// through a third trajectory both are tied to).

#include <cstdint>
#include <functional>
#include <limits>
#include <map>
#include <optional>
#include <unordered_map>
#include <utility>
#include <vector>

#include "common/solver/keys.h"

namespace anchormap {

class TrajectoryTies {
 public:
  // Keyframe a of one trajectory tied to keyframe b of another (a loop closure, within one
  // trajectory, is no tie: ignored).
  void Add(PoseKey a, PoseKey b);
  void Clear() {
    ends_.clear();
    parent_.clear();
  }
  int64_t size() const { return size_; }

  // The shortest drive from `from` to `to`: along each trajectory (`driven(key)`, the path
  // driven from the trajectory's start to that keyframe, nondecreasing in the index),
  // crossing from one trajectory to another only where they are tied (a tie costs nothing).
  // nullopt when no chain of ties connects the two trajectories, or (given `limit`) when
  // the shortest drive is longer than `limit`: the search stops there, so a bounded
  // question ("tied within a few metres of here?") costs the ties near here, not all of them.
  // Not for two threads at once (it keeps its scratch space between calls).
  std::optional<double> ShortestDrive(PoseKey from, PoseKey to,
                                      const std::function<double(PoseKey)>& driven,
                                      double limit = std::numeric_limits<double>::infinity()) const;
  // Whether a chain of ties connects the two trajectories (each is connected to itself): what a
  // bounded ShortestDrive's nullopt leaves open, answered without a search.
  bool Connected(TrajectoryId a, TrajectoryId b) const { return Root(a) == Root(b); }

 private:
  // Per trajectory: its tied keyframes' indices, ascending, and for each the keyframes tied
  // to it. Flat arrays, not ordered maps: the search reads a trajectory's tied keyframes at
  // every keyframe it settles, and with 20 robots after a few hundred seconds of data the
  // maps' pointer chasing was most of the search's time (8 % of the server's CPU at 450 s).
  struct Tied {
    std::vector<int32_t> indices;
    std::vector<std::vector<PoseKey>> partners;
  };
  std::unordered_map<int64_t, Tied> ends_;
  // Union-find over the trajectories the ties connect (absent: alone).
  TrajectoryId Root(TrajectoryId trajectory) const;
  std::map<TrajectoryId, TrajectoryId> parent_;
  int64_t size_ = 0;

  // ShortestDrive's scratch, kept between calls: its queue (a heap) and the keyframes it
  // settled, as an open-addressing set of (trajectory, index) ids cleared through the list
  // of the slots it filled. A std::priority_queue and a std::unordered_set per call spent
  // a third of its samples in malloc (100 robots, 90-120 s of data).
  using Node = std::pair<int64_t, int32_t>;  // (trajectory, index)
  using Item = std::pair<double, Node>;
  class SettledSet {
   public:
    // Adds `id`; false when it was already in.
    bool Insert(uint64_t id);
    bool Contains(uint64_t id) const;
    void Clear();

   private:
    static constexpr uint64_t kEmpty = ~uint64_t{0};
    void Grow();
    std::vector<uint64_t> slots_;
    std::vector<size_t> filled_;
    int shift_ = 64;
  };
  mutable std::vector<Item> queue_;
  mutable SettledSet settled_;
};

}  // namespace anchormap
