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
  // A search settles at most `max_settled` tied keyframes (0: no cap). In a place that many
  // passes tie together the tied keyframes within a few metres of drive grow with every pass
  // (20 robots: thousands after 15 minutes), and each keyframe asks several drives: the cap
  // keeps a question's cost bounded, and its answer says what the search knows (DriveRange).
  static constexpr int64_t kDefaultMaxSettled = 512;
  explicit TrajectoryTies(int64_t max_settled = kDefaultMaxSettled) : max_settled_(max_settled) {}

  // Keyframe a of one trajectory tied to keyframe b of another (a loop closure, within one
  // trajectory, is no tie: ignored).
  void Add(PoseKey a, PoseKey b);
  void Clear();
  int64_t size() const { return size_; }

  // The shortest drive from `from` to `to`: along each trajectory (`driven(key)`, the path
  // driven from the trajectory's start to that keyframe, nondecreasing in the index),
  // crossing from one trajectory to another only where they are tied (a tie costs nothing).
  // nullopt when no chain of ties connects the two trajectories, or (given `limit`) when
  // the shortest drive is longer than `limit`: the search stops there, so a bounded
  // question ("tied within a few metres of here?") costs the ties near here, not all of them.
  // `driven` must give every keyframe the same value at every call (the odometry's path is
  // fixed): the search keeps each tied keyframe's value once asked.
  // Not for two threads at once (it keeps its scratch space between calls).
  std::optional<double> ShortestDrive(PoseKey from, PoseKey to,
                                      const std::function<double(PoseKey)>& driven,
                                      double limit = std::numeric_limits<double>::infinity()) const;
  // What a search knows of the shortest drive: it lies in [at_least, at_most]. Exact (the two
  // equal) when a chain within `limit` is the shortest; at_least >= limit (at_most the shortest
  // chain found, or +inf) when every chain is longer than `limit` or none exists. When the
  // search reached the cap first, at_least is the drive it had reached (no chain is shorter)
  // and at_most the shortest chain it found (+inf: none yet), `capped` set. ShortestDrive is
  // its exact value within the limit (nullopt when capped).
  struct DriveRange {
    double at_least = std::numeric_limits<double>::infinity();
    double at_most = std::numeric_limits<double>::infinity();
    bool capped = false;
  };
  DriveRange Drive(PoseKey from, PoseKey to, const std::function<double(PoseKey)>& driven,
                   double limit = std::numeric_limits<double>::infinity()) const;
  // Whether the shortest drive is below `limit` (strictly): the same answer as ShortestDrive's
  // value < limit, given as soon as one chain of ties below it is found (a saturation check
  // in a place many passes tie together then stops at its first short chain). True too when
  // the search reached the cap first: that many tied keyframes within `limit` of drive make
  // a place tied densely enough.
  bool DriveBelow(PoseKey from, PoseKey to, const std::function<double(PoseKey)>& driven,
                  double limit) const;
  // Whether a chain of ties connects the two trajectories (each is connected to itself): what a
  // bounded ShortestDrive's nullopt leaves open, answered without a search.
  bool Connected(TrajectoryId a, TrajectoryId b) const { return Root(a) == Root(b); }

  // Searches so far, the tied keyframes they settled (in all, and the most in one), and how
  // many reached the cap.
  struct SearchStats {
    int64_t searches = 0;
    int64_t settled = 0;
    int64_t most_settled = 0;
    int64_t capped = 0;
  };
  const SearchStats& search_stats() const { return stats_; }

 private:
  // A tied keyframe: its neighbours among its trajectory's tied keyframes by index (kNone at
  // the ends) and the keyframes tied to it, all as positions in nodes_, so that the search
  // follows edges without lookups (with 20 robots after a few hundred seconds of data the
  // tied keyframes of a place number thousands, and the search settles all of them).
  static constexpr int32_t kNone = -1;
  struct Node {
    PoseKey key;
    int32_t below = kNone;
    int32_t above = kNone;
    std::vector<int32_t> partners;
    // driven(key), once asked (NaN before).
    mutable double driven = std::numeric_limits<double>::quiet_NaN();
  };
  // Per trajectory: its tied keyframes' indices, ascending, and their nodes.
  struct Tied {
    std::vector<int32_t> indices;
    std::vector<int32_t> nodes;
  };
  // The node of `key`, added when new.
  int32_t NodeOf(PoseKey key);
  double DrivenOf(int32_t node, const std::function<double(PoseKey)>& driven) const;
  // Dijkstra from `from`; with `below`, stops at the first drive to `to` under `limit`.
  DriveRange Search(PoseKey from, PoseKey to, const std::function<double(PoseKey)>& driven,
                    double limit, bool below) const;

  std::vector<Node> nodes_;
  std::unordered_map<int64_t, Tied> ends_;
  // Union-find over the trajectories the ties connect (absent: alone).
  TrajectoryId Root(TrajectoryId trajectory) const;
  std::map<TrajectoryId, TrajectoryId> parent_;
  int64_t size_ = 0;
  int64_t max_settled_;
  mutable SearchStats stats_;

  // The search's scratch, kept between calls: its queue (a min-heap on distance, then
  // trajectory and index, as before the nodes had positions: the same order of settling) and
  // a stamp per node, the search's number when it settled there.
  struct Item {
    double distance;
    int64_t trajectory;
    int32_t index;
    int32_t node;
  };
  mutable std::vector<Item> queue_;
  mutable std::vector<uint32_t> settled_in_;
  mutable uint32_t search_ = 0;
};

}  // namespace anchormap
