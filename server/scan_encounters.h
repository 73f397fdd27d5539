#pragma once
// Encounters between trajectories found by scan matching (issue 11, items 4 and 5), the
// EncounterSource beside the direct one. Each trajectory's solved keyframes are cut into
// submaps (KeyframeSubmap: 2 half_width + 1 keyframes every submap_stride, drawn once at
// the estimates of the time). A keyframe is examined once the smoother has solved it:
// - against a trajectory not in its anchored group (no prior): every global_every-th
//   keyframe is searched globally (GlobalSearch, every heading, the submap's whole grid)
//   in up to max_global_per_keyframe of the other's submaps, taken in turn (or near where a
//   kept hypothesis puts the keyframe: guide_*), against at
//   most max_global_groups_per_keyframe other groups and within a team-wide budget per
//   second of data (GlobalSearchQueue: the cost does not grow with the team); when groups
//   change, past keyframes a kept hypothesis puts near a submap of a trajectory newly in its
//   group are searched there once (look_back_*). A match with
//   enough score and overlap is a candidate, not yet a constraint: a first encounter
//   joins two groups only when two candidates of the same pair of trajectories at
//   different places agree through each trajectory's own estimate (pairwise consistency,
//   Mangelson et al., ICRA 2018: the loop candidate 1, odometry in one, candidate 2
//   reversed, odometry in the other, is the identity within the chi-square gate). Only
//   matches localised in every direction take part (first_join_max_sigma_*: a corridor
//   match is free along it and agrees with anything there), and the candidates that join
//   agree pair by pair, not only with the best supported one. Two candidates whose own maps
//   agree (map-verified: few of either side's points in the other's seen free space) are
//   tested with each trajectory's estimate widened for the drive and the turn between them.
//   Two map-verified candidates also confirm each other from one place of one trajectory
//   when they come from two query scans, two looks rather than one (pcm_max_shared_look),
//   matched against two stretches of the other that share no keyframe and see other walls
//   (the other robot saw the place twice). Once a
//   group holds two trajectories or more, two map-verified candidates of two pairs between the
//   same groups (R1-R3 and R2-R3, R1 and R2 joined) confirm each other too: each side's
//   relative pose comes from its group's joint estimate, and they must be at two places of
//   both groups as above. Lone
//   candidates are kept (at most max_kept per pair); when the pair comes into one frame
//   by other evidence (a direct encounter) they are gated against the estimate instead.
//   A symmetric building makes whole sets of wrong candidates agree with each other (the
//   place turned by 180 degrees): a hypothesis joins only when it has at least twice the
//   support of any kept candidate it disagrees with (alternative_ratio), so that two
//   supported hypotheses wait for more evidence or a direct encounter. Last, the maps
//   around the matched places must not contradict each other (join_max_conflict: walls of
//   one in the other's seen free space); a refused set takes no further part in a first
//   join (its candidates stay kept, gated if the pair joins otherwise; counted as
//   joins_contradicted);
// - against a trajectory of its group: when the predicted distance to one of the other's
//   submap centres is below near_distance_m (the thesis' 4 m), a window search around
//   the prediction; accepted with overlap >= near_min_overlap (85 %) and a chi-square
//   gate against the estimate and the joint covariance. The window and a second gate add
//   a drift term for the path both robots drove since the nearest tie between them
//   (near_drift_*): a match only that gate accepts enters with a second one that agrees.
//   When a pair first comes into one frame, the keyframes examined before are searched
//   so once (near_catch_up_every). A pair that joins at the end of input gets this catch-up
//   and its kept candidates gated too: Flush keeps them, and MappingServer::Flush solves the
//   join and calls Flush once more. A pair already tied near here is not searched again
//   (near_saturation_m), and a keyframe searches at most near_max_partners joined
//   trajectories, the nearest first: the work per keyframe does not grow with the team;
//   and the near searches per second of data are bounded (near_budget,
//   server/match_budget.h): the work per second does not grow with the team either.
// The matches run on the MatchPool's workers (or on the caller's thread without a pool);
// their results are used when the canonical input reaches the keyframe's time plus the
// schedule's lag, waiting for them if needed: deterministic, whatever the worker count.
// ScanEncounters is the pipeline; its parts, each with its own state (the options, with the
// measurements behind them: scan_encounter_options.h):
// - EncounterSubmaps (encounter_submaps.h): every trajectory's submaps and their references;
// - EncounterMatches (encounter_matches.h): the matches in flight, used in order when due;
// - JoinQualifier (join_qualifier.h): the kept candidates and the first join;
// - NearSearch (near_search.h): the near search between joined trajectories;
// - GlobalSearchPlanner (global_search_planner.h): the global search of unjoined ones;
// - LookBackPlanner (look_back_planner.h): the look back on group change.

#include <cstddef>
#include <cstdint>
#include <deque>
#include <string>

#include <Eigen/Core>

#include "common/solver/keys.h"
#include "server/candidate_stats.h"
#include "server/driven_path.h"
#include "server/encounter_candidate.h"
#include "server/encounter_matches.h"
#include "server/encounter_source.h"
#include "server/encounter_submaps.h"
#include "server/global_search_planner.h"
#include "server/global_search_queue.h"
#include "server/join_qualifier.h"
#include "server/look_back_planner.h"
#include "server/match_budget.h"
#include "server/match_pool.h"
#include "server/near_search.h"
#include "server/scan_encounter_options.h"
#include "server/scan_encounter_state.h"

namespace anchormap {

class ScanEncounters : public EncounterSource {
 public:
  // Without a pool, matches run on the caller's thread and are used at once.
  explicit ScanEncounters(const ScanEncounterOptions& options = {}, MatchPool* pool = nullptr,
                          MatchSchedule schedule = {})
      : options_(options),
        qualifier_(options, &stats_, &driven_, name()),
        submaps_(options),
        matches_(pool, schedule),
        near_(options, &stats_, &driven_, &submaps_, &matches_, name()),
        global_(options, &submaps_, &qualifier_, &matches_),
        look_back_(options, &driven_, &submaps_, &qualifier_, &near_, &matches_) {}
  // The parts hold pointers to each other.
  ScanEncounters(const ScanEncounters&) = delete;
  ScanEncounters& operator=(const ScanEncounters&) = delete;

  std::string name() const override { return "scan"; }
  void OnKeyframeAdded(PoseKey key, const GraphView& graph, EncounterSourceOutput* out) override;
  void Poll(int64_t now_utime, const GraphView& graph, EncounterSourceOutput* out) override;
  void Flush(const GraphView& graph, EncounterSourceOutput* out) override;
  size_t pending() const override {
    return waiting_.size() + matches_.size() + global_.queue().waiting();
  }
  std::string StatsLine() const override;
  const CandidateStats& stats() const { return stats_; }
  int64_t joins_contradicted() const { return qualifier_.joins_contradicted(); }
  int64_t near_saturated() const { return near_.saturated(); }
  int64_t near_capped() const { return near_.capped(); }
  int64_t look_backs() const { return look_back_.look_backs(); }
  const GlobalSearchQueue& global_searches() const { return global_.queue(); }
  const MatchBudget& near_budget() const { return near_.budget(); }

  // The source's state for snapshots (scan_encounter_state.h, defined in
  // scan_encounter_state.cc): ExportState waits for the matches in flight; ImportState is for
  // a source given no input.
  ScanEncounterState ExportState() const;
  void ImportState(const ScanEncounterState& state);

  // A candidate from outside the matcher (tests inject false ones): it takes the same
  // path as a matched one (pairwise consistency when unjoined, the gate when joined).
  void OfferCandidate(const EncounterCandidate& candidate, const GraphView& graph,
                      EncounterSourceOutput* out);
  // A match of a near search (tests offer hand-made ones), a the other's submap, b the query.
  // `wide` (its window was wider than max_window_m): gated with the widened covariance, then
  // held until a second one agrees (both enter then). Otherwise: entered at once when the
  // plain gate accepts it; else, when the gate with the drift term accepts it, held as a wide
  // one is.
  void OfferNearMatch(const EncounterCandidate& candidate, bool wide, const GraphView& graph,
                      EncounterSourceOutput* out);
  // The drift term of the relative pose of keyframe b seen from keyframe a, two joined
  // trajectories (zero without the graph's ties, or when none connects them).
  Eigen::Matrix3d NearDrift(PoseKey a, PoseKey b, const GraphView& graph);
  // The same for a near search's window (NearSearchWindow): the tie graph searched only as far
  // as the window keeps growing with the drive (NearWindowSaturatingDrive), the same window.
  Eigen::Matrix3d NearWindowDrift(PoseKey a, PoseKey b, const GraphView& graph);

 private:
  // `at_end`: folded keyframes are examined without waiting for folded_wait_s.
  void Examine(const GraphView& graph, EncounterSourceOutput* out, bool at_end = false);
  // A folded keyframe still within folded_wait_s of its own time (data time, now_utime_).
  bool FoldedTooRecently(PoseKey key, const GraphView& graph) const;
  // `near_too`: its near searches too (else only its global search, which has its own
  // budget). Returns the near searches submitted.
  int ExamineKeyframe(PoseKey key, const GraphView& graph, bool near_too);
  // The path `key`'s odometry drove from its trajectory's first keyframe (0 without its record).
  double DrivenTo(PoseKey key, const GraphView& graph);

  // Uses the matches due now (all when `all`), in the order they were made.
  void UseMatches(bool all, const GraphView& graph, EncounterSourceOutput* out);
  // Kept candidates of pairs that came into one frame: gated against the estimate.
  void ResolveKept(const GraphView& graph, EncounterSourceOutput* out);
  // True when the chi-square gate against the estimate accepts `candidate` (a refusal is
  // counted); `widened`: the prediction's covariance widened in every direction by its largest
  // translational sigma (the wide near search's matches).
  bool PassesGate(const EncounterCandidate& candidate, const GraphView& graph, bool widened);
  // True when the gate against the estimate accepts it (counts either way).
  bool GateAndEmit(const EncounterCandidate& candidate, const GraphView& graph,
                   EncounterSourceOutput* out);
  void Emit(const EncounterCandidate& candidate, EncounterSourceOutput* out);

  ScanEncounterOptions options_;
  CandidateStats stats_;
  DrivenPath driven_;  // a function of the table, so not in snapshots
  JoinQualifier qualifier_;
  EncounterSubmaps submaps_;
  EncounterMatches matches_;
  NearSearch near_;
  std::deque<PoseKey> waiting_;
  GlobalSearchPlanner global_;
  LookBackPlanner look_back_;
  int64_t now_utime_ = 0;
  int64_t near_folded_ = 0;  // keyframes not near-searched from: folded (reduced graph)
};

}  // namespace anchormap
