#pragma once
// A prototype of the solver's side of a reduced pose graph (docs/ARCHITECTURE.md, "Bounding
// the graph by area (rpg23)"): a team's keyframes and links, in time order, go into the
// server's smoother (ServerModeWithCorrectionOptions) either as the full graph (a pose per
// keyframe, as the server does now) or as the reduced graph (a pose per AreaNodeSelector
// node; a folded keyframe is its node plus a matched offset, and its odometry and links
// become factors between nodes), with an Update() every `period_s` of data time.
// Measurements are the truth plus seeded Gaussian noise (the same draws for both graphs),
// so the figures are the solver's cost on this structure, not the server's maps.

#include <cstdint>
#include <vector>

#include "common/geometry/pose2.h"
#include "common/util/status.h"
#include "tools/bench/area_node_selector.h"

namespace anchormap {

struct AreaReplayKeyframe {
  int64_t utime = 0;
  int trajectory = 0;  // 0 .. trajectories - 1
  Pose2 truth;
};

struct AreaReplayLink {  // a loop closure or encounter between two keyframes (positions)
  int64_t utime = 0;     // when it can enter: not before its later keyframe
  int a = 0;
  int b = 0;
};

struct AreaReplayOptions {
  bool reduced = false;
  AreaNodeRule rule;
  double period_s = 0.5;
  double until_s = 1e18;  // data seconds after the first keyframe to replay
  uint64_t seed = 1;
};

struct AreaReplayUpdate {
  double data_s = 0.0;  // since the first keyframe
  double cpu_s = 0.0;   // of the Update() (thread CPU)
  int64_t variables = 0;
  int64_t factors = 0;
  int64_t nnz_r = 0;
  bool batch_step = false;  // the update relinearised and reordered everything
};

struct AreaReplayAccuracy {
  // The RMS distance between each replayed keyframe's estimate (its node's global pose
  // composed with its offset) and its truth, after the last update and after a final
  // BatchOptimize() (as the server runs at the end of input). The frames are the truth's
  // (each trajectory's first pose is placed at its truth), so no alignment.
  double after_updates_m = 0.0;
  double after_batch_m = 0.0;
};

// Keyframes sorted by time; links sorted by time, each at or after its keyframes'.
// `accuracy` may be null (no final batch step then).
Status ReplayAreaGraph(const std::vector<AreaReplayKeyframe>& keyframes,
                       const std::vector<AreaReplayLink>& links, int trajectories,
                       const AreaReplayOptions& options, std::vector<AreaReplayUpdate>* updates,
                       AreaReplayAccuracy* accuracy = nullptr);

}  // namespace anchormap
