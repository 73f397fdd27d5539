#pragma once
// The near search between trajectories of one group (issue 11, item 5): when the predicted
// distance from a solved keyframe to one of the other's submap centres is below near_distance_m
// (the thesis' 4 m), a window search around the prediction (NearSearchWindow), accepted with
// overlap >= near_min_overlap and a chi-square gate against the estimate and the joint
// covariance. The window and a second gate add a drift term for the path both robots drove
// since the nearest tie between them (near_drift_*): a match only that gate accepts, or one of a
// window wider than max_window_m, enters with a second one that agrees (HoldForPair). A pair
// already tied near here is not searched again (near_saturation_m), a keyframe searches at most
// near_max_partners joined trajectories, the nearest first, and the searches per second of data
// are bounded (near_budget): the work per keyframe and per second does not grow with the team.
// When a pair first comes into one frame, the keyframes examined before are searched so once
// (CatchUpJoined). The options and the measurements behind them:
// server/scan_encounter_options.h.

#include <cstddef>
#include <cstdint>
#include <deque>
#include <map>
#include <optional>
#include <set>
#include <string>
#include <utility>
#include <vector>

#include <Eigen/Core>

#include "common/scan_matching/correlative_matcher.h"
#include "common/solver/keys.h"
#include "server/candidate_stats.h"
#include "server/driven_path.h"
#include "server/encounter_candidate.h"
#include "server/encounter_matches.h"
#include "server/encounter_source.h"
#include "server/encounter_submaps.h"
#include "server/match_budget.h"
#include "server/position_index.h"
#include "server/relative_pose.h"
#include "server/scan_encounter_options.h"
#include "server/scan_encounter_state.h"

namespace anchormap {

// The near drift term for a drive of `drive_m` through the ties (near_drift_per_m,
// near_drift_rad_per_m).
Eigen::Matrix3d NearDriftOf(double drive_m, const ScanEncounterOptions& options);
// A drive from which NearSearchWindow's window, with that drift term added, is its widest in
// translation and rotation whatever the prediction's covariance: a longer drive gives the
// same window.
double NearWindowSaturatingDrive(const ScanEncounterOptions& options);
// The near search's window around a prediction of covariance `covariance` (the drift term
// included): 3 sigma within [min_window, max_window], or, when 3 sigma exceeds max_window_m,
// up to near_wide_max_window_m (`wide`, with the acceptance bar as the lattice's bar).
LocalMatchOptions NearSearchWindow(const Eigen::Matrix3d& covariance,
                                   const ScanEncounterOptions& options, bool* wide);

class NearSearch {
 public:
  // The submap of `other` a near search of a keyframe would match against.
  struct NearTarget {
    TrajectoryId other;
    size_t submap = 0;  // in the submaps of `other`
    double distance = 0.0;
  };

  // `stats`, `driven`, `submaps` and `matches` are the scan encounters' (shared with their
  // other parts); accepted matches are entered as from `source_name`.
  NearSearch(const ScanEncounterOptions& options, CandidateStats* stats, DrivenPath* driven,
             EncounterSubmaps* submaps, EncounterMatches* matches, std::string source_name)
      : options_(options),
        stats_(stats),
        driven_(driven),
        submaps_(submaps),
        matches_(matches),
        source_name_(std::move(source_name)),
        near_budget_(options.near_budget) {}

  // Data time advanced (the index refresh, the budget's tokens).
  void Advance(int64_t now_utime) {
    now_utime_ = now_utime;
    near_budget_.Advance(now_utime_);
  }
  // The joined trajectories `key` is near-searched against (FindNear), nearest first, at most
  // near_max_partners (the others counted as capped).
  std::vector<NearTarget> Targets(PoseKey key, const GraphView& graph);
  // The nearest submap of `other` within near_distance_m, unless the pair is quiet or saturated
  // there (nullopt then).
  std::optional<NearTarget> FindNear(PoseKey key, TrajectoryId other, const GraphView& graph);
  // True when a match was submitted.
  bool SearchNear(PoseKey key, const NearTarget& target, const GraphView& graph);
  // Near-searches the keyframes examined before a pair came into one frame (once per pair), but
  // those waiting to be examined (`waiting_keys`).
  void CatchUpJoined(const TrajectoryFrames& frames, const std::deque<PoseKey>& waiting_keys,
                     const GraphView& graph);
  // A match of a near search, a the other's submap, b the query. `wide` (its window was wider
  // than max_window_m): gated with the widened covariance, then held until a second one agrees
  // (both enter then). Otherwise: entered at once when the plain gate accepts it; else, when
  // the gate with the drift term accepts it, held as a wide one is.
  void OfferNearMatch(const EncounterCandidate& candidate, bool wide, const GraphView& graph,
                      EncounterSourceOutput* out);
  // End of input: the held matches are given up.
  void GiveUpHeld();
  // The drift term of the relative pose of keyframe b seen from keyframe a, two joined
  // trajectories (zero without the graph's ties, or when none connects them).
  Eigen::Matrix3d NearDrift(PoseKey a, PoseKey b, const GraphView& graph);
  // The same for a near search's window (NearSearchWindow): the tie graph searched only as far
  // as the window keeps growing with the drive (NearWindowSaturatingDrive), the same window.
  Eigen::Matrix3d NearWindowDrift(PoseKey a, PoseKey b, const GraphView& graph);

  MatchBudget& budget() { return near_budget_; }
  const MatchBudget& budget() const { return near_budget_; }
  int64_t saturated() const { return near_saturated_; }
  int64_t capped() const { return near_capped_; }

  // Snapshots (scan_encounter_state.h): cooldowns, held matches, indexes, budget, the pairs
  // caught up.
  void ExportState(ScanEncounterState* s) const;
  void ImportState(const ScanEncounterState& s);

 private:
  using Pair = std::pair<TrajectoryId, TrajectoryId>;
  using Submap = EncounterSubmaps::Submap;
  // True when the pair is tied within near_saturation_m of drive between `key` and `center`.
  bool Saturated(PoseKey key, PoseKey center, const GraphView& graph);
  // Holds a match accepted only by a widened gate until a second one agrees; both enter then.
  void HoldForPair(const EncounterCandidate& candidate, const GraphView& graph,
                   EncounterSourceOutput* out);

  ScanEncounterOptions options_;
  CandidateStats* stats_;
  DrivenPath* driven_;
  EncounterSubmaps* submaps_;
  EncounterMatches* matches_;
  std::string source_name_;
  int64_t now_utime_ = 0;
  // Near searches skipped as saturated, and beyond near_max_partners (counts only, like
  // joins_contradicted: not in snapshots).
  int64_t near_saturated_ = 0;
  int64_t near_capped_ = 0;
  std::map<Pair, int32_t> near_quiet_until_;                  // keyed (examined trajectory, other)
  std::map<Pair, std::deque<EncounterCandidate>> near_held_;  // keyed as near_quiet_until_
  // Per trajectory, its submaps' centres in its frame (items: positions in its submaps).
  struct SubmapIndex {
    PositionIndex index{4.0};
    size_t indexed = 0;  // submaps in the index
    int64_t refreshed_utime = 0;
    int64_t merges = -1;  // the smoother's merge count at the refresh
  };
  // The index of `other`'s submaps, refreshed when due.
  const PositionIndex& NearIndex(TrajectoryId other, const GraphView& graph);
  std::map<TrajectoryId, SubmapIndex> near_index_;
  MatchBudget near_budget_;
  // The pairs of trajectories seen in one frame (caught up); false after restoring a snapshot
  // that held none: the pairs in one frame then are taken as caught up.
  std::set<Pair> near_joined_;
  bool near_joined_known_ = true;
  // The frames (FramesOf) at the last CatchUpJoined. While they are the same, no pair is
  // newly in one frame and the walk over all pairs (quadratic in the robots, at every
  // keyframe: 15 % of the replay at 100 robots) is skipped. A cache, not in snapshots: empty
  // after ImportState.
  TrajectoryFrames caught_up_frames_;
};

}  // namespace anchormap
