#include "common/solver/anchor_groups.h"

#include <utility>

namespace anchormap {

void AnchorGroups::CreateGroup(TrajectoryId trajectory, int64_t prior_id) {
  parent_[trajectory] = trajectory;
  created_[trajectory] = next_created_++;
  prior_[trajectory] = prior_id;
}

void AnchorGroups::Join(TrajectoryId trajectory, TrajectoryId member) {
  parent_[trajectory] = Root(member);
}

TrajectoryId AnchorGroups::Root(TrajectoryId trajectory) const {
  // Few trajectories and shallow trees: no path compression needed (keeps Root const).
  TrajectoryId t = trajectory;
  while (true) {
    const TrajectoryId p = parent_.at(t);
    if (p == t) return t;
    t = p;
  }
}

AnchorGroups::Merge AnchorGroups::MergeGroups(TrajectoryId a, TrajectoryId b) {
  TrajectoryId survivor = Root(a), absorbed = Root(b);
  if (created_.at(absorbed) < created_.at(survivor)) std::swap(survivor, absorbed);
  parent_[absorbed] = survivor;
  const Merge merge{survivor, absorbed, prior_.at(absorbed)};
  prior_.erase(absorbed);
  created_.erase(absorbed);
  return merge;
}

}  // namespace anchormap
