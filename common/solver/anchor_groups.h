#pragma once
// Groups of trajectories that share one frame, each with exactly one gauge prior
// (docs/METHOD.md section 4): a union-find over trajectories in which the group created
// first survives a merge, and the absorbed group's gauge prior is handed back so the
// smoother can remove it. Relative formulation: groups of anchored trajectories, the
// prior sits on the group's first anchor. Global formulations: every trajectory starts
// as its own group, the prior sits on its first pose.

#include <cstdint>
#include <optional>
#include <unordered_map>

#include "common/solver/keys.h"

namespace anchormap {

class AnchorGroups {
 public:
  // Starts a new group with `trajectory` as its root, fixed by prior factor `prior_id`.
  void CreateGroup(TrajectoryId trajectory, int64_t prior_id);
  // Adds `trajectory` (in no group yet) to the group of `member`.
  void Join(TrajectoryId trajectory, TrajectoryId member);
  bool Contains(TrajectoryId trajectory) const { return parent_.count(trajectory) > 0; }
  // Root trajectory of the group (precondition: Contains).
  TrajectoryId Root(TrajectoryId trajectory) const;
  bool SameGroup(TrajectoryId a, TrajectoryId b) const { return Root(a) == Root(b); }

  struct Merge {
    TrajectoryId surviving_root;
    TrajectoryId absorbed_root;
    int64_t absorbed_prior_id;  // the gauge prior to remove
  };
  // Merges the groups of a and b (precondition: both contained, different groups). The
  // group created earlier survives.
  Merge MergeGroups(TrajectoryId a, TrajectoryId b);

  int64_t PriorOf(TrajectoryId trajectory) const { return prior_.at(Root(trajectory)); }

 private:
  std::unordered_map<TrajectoryId, TrajectoryId> parent_;
  std::unordered_map<TrajectoryId, int64_t> created_;  // creation order of group roots
  std::unordered_map<TrajectoryId, int64_t> prior_;    // gauge prior of each root
  int64_t next_created_ = 0;
};

}  // namespace anchormap
