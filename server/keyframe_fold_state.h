#pragma once
// The reduced graph's folder state (KeyframeFolder::ExportState / ImportState), for snapshots
// (server/snapshot_codec.h; written by server/source_state_codec.h): what decides the next
// folds beyond the graph itself. The node table (each node with the keyframe whose scan
// verifies a fold onto it), the position index as it stands (the positions read at the update
// it was built at, plus the nodes added since at their estimates then: the restored folder
// asks exactly what the live one would, whatever moved since; rebuilding it at the restore gave
// the same folds in reduced_graph_test.cc, but not the same bytes), and the counters. Not
// held: the cache of node scan references, rebuilt on demand from the keyframes' scans (the
// same reference, so the same matches).

#include <cstdint>
#include <utility>
#include <vector>

#include <Eigen/Core>

#include "common/solver/keys.h"
#include "server/keyframe_fold.h"
#include "server/relative_pose.h"

namespace anchormap {

struct KeyframeFolderState {
  struct Node {
    PoseKey node;
    PoseKey keyframe;
  };
  std::vector<Node> nodes;  // in the order added (the index's items)
  // The index: per frame (in the map's order), its (item, position) entries in PositionIndex::
  // Entries order; the smoother update it was built at (-1: none yet).
  std::vector<std::pair<TrajectoryFrame, std::vector<std::pair<int32_t, Eigen::Vector2d>>>> index;
  int64_t indexed_at_update = -1;
  KeyframeFoldStats stats;
};

}  // namespace anchormap
