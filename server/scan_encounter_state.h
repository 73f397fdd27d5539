#pragma once
// ScanEncounters' private state as plain values (issue 13: snapshots with the scan-matching
// sources on), exported and imported by the source (ScanEncounters::ExportState /
// ImportState) and written by server/source_state_codec.h. Held: the submaps' drawings (drawn
// at the estimate of their time, not of now), the near-search indexes (positions of their
// last refresh), the global-search budget, kept candidates, cooldowns and counters. Not
// held: the submap references (a pure function of their drawing: SubmapCache) and the pool.
// Matches in flight are held with their results (ExportState waits for them): the restored
// source consumes the results the uninterrupted one would, at the same point of the input.

#include <cstddef>
#include <cstdint>
#include <map>
#include <optional>
#include <set>
#include <utility>
#include <vector>

#include <Eigen/Core>

#include "common/scan_matching/correlative_matcher.h"
#include "common/solver/keys.h"
#include "server/candidate_stats.h"
#include "server/global_search_queue.h"
#include "server/keyframe_submap.h"
#include "server/match_budget.h"

namespace anchormap {

// A candidate encounter: keyframe b measured in the frame of keyframe a (as ScanEncounters'
// EncounterCandidate, whose header includes this one).
struct ScanEncounterCandidateState {
  PoseKey a;
  PoseKey b;
  Pose2 T_a_b;
  Eigen::Matrix3d covariance = Eigen::Matrix3d::Identity();
  int64_t utime = 0;
  bool a_is_query = false;
};

struct ScanEncounterState {
  using Pair = std::pair<TrajectoryId, TrajectoryId>;
  struct Match {
    int64_t due_utime = 0;
    PoseKey key;
    PoseKey center;
    bool global = false;
    bool wide = false;  // a near search's wide window (snapshot version 5)
    int64_t key_utime = 0;
    std::optional<MatchResult> result;
  };
  struct Kept {
    ScanEncounterCandidateState candidate;
    int support = 0;
    bool localised = true;
    bool verified = false;  // its own maps agree (snapshot version 7; before, none was)
    // Its own maps' conflict and the fewer side's points, measured when it was offered
    // (snapshot version 10; before, none was measured: 1 and 0, it guides no search).
    double conflict = 1.0;
    int64_t conflict_points = 0;
  };
  struct NearIndex {
    std::vector<std::pair<int32_t, Eigen::Vector2d>> entries;  // PositionIndex's items
    size_t indexed = 0;
    int64_t refreshed_utime = 0;
    int64_t merges = -1;
  };
  std::vector<Match> matches;
  std::vector<PoseKey> waiting;
  std::map<TrajectoryId, std::vector<std::pair<PoseKey, SubmapDrawing>>>
      submaps;  // (centre, drawing)
  std::map<Pair, size_t> global_cursor;
  GlobalSearchQueue::State global_queue;
  std::map<Pair, std::vector<Kept>> kept;
  std::map<Pair, int64_t> qualified_since;
  int64_t now_utime = 0;
  std::map<Pair, int32_t> near_quiet_until;
  std::map<TrajectoryId, NearIndex> near_index;
  CandidateStats stats;
  // Wide near matches waiting for a second one (snapshot version 5), keyed (query, other).
  std::map<Pair, std::vector<ScanEncounterCandidateState>> near_held;
  // The pairs of trajectories seen in one frame, whose earlier keyframes were near-searched
  // (snapshot version 6); near_joined_known false when read from an older one.
  std::set<Pair> near_joined;
  bool near_joined_known = true;
  // The near searches' matching budget (none in snapshots before version 9: the restored
  // source keeps a fresh one).
  std::optional<MatchBudget::State> near_budget;
  // Keyframes not near-searched from: folded (the reduced graph; 0 in snapshots before
  // version 12).
  int64_t near_folded = 0;
};

}  // namespace anchormap
