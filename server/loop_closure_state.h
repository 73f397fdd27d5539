#pragma once
// LoopClosures' private state as plain values (issue 13: snapshots with the scan-matching
// sources on), exported and imported by the source (LoopClosures::ExportState / ImportState)
// and written by server/source_state_codec.h. Not held: the submap references (a pure
// function of their drawing, built again when needed: SubmapCache) and the pool.
//
// Matches in flight are held with their results: ExportState waits for them (they would be
// waited for at the next input anyway, at lag 0), so the restored source consumes exactly the
// results the uninterrupted one would, journaled or not, at the same point of the input.

#include <cstdint>
#include <map>
#include <optional>
#include <set>
#include <utility>
#include <vector>

#include <Eigen/Core>

#include "common/geometry/pose2.h"
#include "common/scan_matching/correlative_matcher.h"
#include "common/scan_matching/point_cloud.h"
#include "common/solver/keys.h"
#include "server/candidate_stats.h"
#include "server/match_budget.h"
#include "server/relative_pose.h"

namespace anchormap {

struct LoopClosureState {
  // A wide match waiting for a consistent second.
  struct Hypothesis {
    PoseKey candidate;
    PoseKey key;
    Pose2 measured;
    Eigen::Matrix3d covariance = Eigen::Matrix3d::Identity();
    int64_t key_utime = 0;
    bool weak = false;  // enters only with a strong partner (LoopClosureOptions)
  };
  // A match on its way, with its result.
  struct Match {
    int64_t due_utime = 0;
    PoseKey candidate;
    PoseKey key;
    int64_t key_utime = 0;
    PredictedRelativePose predicted;
    bool wide = false;
    Eigen::Matrix3d drift = Eigen::Matrix3d::Zero();
    PointCloud query;  // wide only
    std::vector<std::pair<int32_t, Pose2>> submap_poses;
    std::optional<MatchResult> result;
    bool has_rival = false;  // wide: the local match it competes with
    std::optional<MatchResult> rival;
  };
  std::vector<Match> matches;
  int64_t now_utime = 0;
  std::vector<PoseKey> waiting;
  std::map<TrajectoryId, int32_t> quiet_until;
  std::map<TrajectoryId, int32_t> next_wide;
  std::map<TrajectoryId, std::vector<Hypothesis>> kept;
  std::map<TrajectoryId, int32_t> last_closure;
  std::map<TrajectoryId, std::set<std::pair<int32_t, int32_t>>> entered;
  CandidateStats stats;
  int64_t wide_searches = 0;
  int64_t ambiguous = 0;
  // The matching budget (none in snapshots before version 9: the restored source keeps a
  // fresh one).
  std::optional<MatchBudget::State> budget;
  // Keyframes not searched from: folded (the reduced graph; 0 in snapshots before version 12).
  int64_t folded = 0;
};

}  // namespace anchormap
