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

#include <cstdint>
#include <deque>
#include <functional>
#include <map>
#include <memory>
#include <optional>
#include <set>
#include <string>
#include <utility>
#include <vector>

#include "common/scan_matching/correlative_matcher.h"
#include "common/scan_matching/free_space_conflict.h"
#include "common/scan_matching/global_search.h"
#include "common/scan_matching/scan_reference.h"
#include "common/util/status.h"
#include "server/candidate_stats.h"
#include "server/driven_path.h"
#include "server/encounter_source.h"
#include "server/global_search_queue.h"
#include "server/join_free_space.h"
#include "server/keyframe_submap.h"
#include "server/match_budget.h"
#include "server/match_pool.h"
#include "server/position_index.h"
#include "server/relative_pose.h"
#include "server/scan_encounter_state.h"
#include "server/submap_cache.h"

namespace anchormap {

struct ScanEncounterOptions {
  int submap_half_width = 5;
  int submap_stride = 10;
  double max_range_m = 15.0;
  // Unjoined trajectories: global search.
  // The global search is the costly part (the server matches on its event loop): every
  // 5th keyframe, 2 submaps of each target (the multiprocess test's server fell behind
  // real time with 3, 4), in at most 2 other groups per keyframe (one trajectory of each:
  // a join with any of them joins the group), within the team-wide budget.
  int global_every = 5;
  int max_global_per_keyframe = 2;  // submaps of one target trajectory, taken in turn
  int max_global_groups_per_keyframe = 2;
  GlobalSearchBudgetOptions global_budget;
  double global_min_score = 0.55;
  double global_min_overlap = 0.7;
  // The pairwise test at 95 %, not 99 %: a first join cannot be undone, while a true pair
  // refused now is offered again with the next candidates. On ACES 3 robots simultaneous
  // a 180-degree copy of R1's start area passed at chi2 10.6 and 10.9 (R1 joined to R3
  // 35 m off); the true pairs measured there and on FR079 2 robots gave 2.2-6.6.
  double pcm_chi2 = 7.81;  // 3 dof, 95 %
  // Two candidates confirm each other only from two places, in each trajectory: at least
  // this many keyframes apart and this far apart in the trajectory's own estimate.
  // Keyframes come every 0.5 m or 0.35 rad, so a robot turning on the spot makes ten in
  // one place (ACES 2 robots simultaneous: R2's candidates 70 and 90 lay 0.97 m apart and
  // joined the robots 3 m off). The true pairs measured on FR079 and ACES were 1.8 m and
  // more apart: the bar is low, for scans taken at one spot.
  int pcm_min_separation = 10;
  double pcm_min_separation_m = 1.5;
  // Distance is not independence: two places count as two only when, in at least one of
  // the trajectories, their keyframes' scans share less than this of what they see (the
  // larger share of either scan's points near the other's, at the estimate). On ACES 3
  // robots simultaneous R1[15]/R1[5] (2 m apart) shared 0.55 and R3[25]/R3[45] (5.6 m
  // apart) 0.59: one view of a 180-degree copy, seen twice, joined R1 to R3 27-38 m off.
  // The true joining pairs measured on Intel, ACES and FR079 had one side at 0.44 or less
  // (FR079 2 robots: R1 0.00, turned round, with R2 0.64).
  double pcm_max_shared_view = 0.5;
  // Two map-verified candidates from one place of the querying robot (Independent) count as
  // two looks only when its two query scans share less than this of their view: one look
  // matched twice confirms nothing, since an aliased corridor matches it at every stretch that
  // looks alike (TwinCorridorWorld, R1 turning on the spot: every pair whose references passed
  // shared 0.944 or more, searching every keyframe against every submap; it joined R2 10 m
  // off). The one-place pairs of the benchmark logs split in two and three measured 0.31-0.89;
  // the one that joins ACES split in three sequentially (R2[180]/R2[185]) 0.745.
  double pcm_max_shared_look = 0.9;
  int max_kept = 200;  // lone candidates kept per pair of trajectories
  // A consistent set joins when (1 + its consistent kept candidates) is at least this
  // times (1 + the support) of every kept candidate outside it.
  double alternative_ratio = 2.0;
  // A first encounter rests only on candidates the matcher localised in every direction
  // (largest translational / heading sigma of its covariance at most these). Along a
  // corridor a match is free: the matcher reports its window prior's sigma there (0.5 m,
  // score_covariance.h), and two such matches agree on a wrong transform by sliding
  // (Intel, 2 robots simultaneous: R1[65]-R2[195] and R1[75]-R2[225], each 0.5 m along
  // its corridor, passed the pairwise test and joined the robots 0.56 rad off). They are
  // kept all the same, and gated against the estimate once the pair is in one frame.
  double first_join_max_sigma_m = 0.1;
  double first_join_max_sigma_rad = 0.05;
  // A qualified first encounter waits this long (data time) before it joins: a direct,
  // identified encounter arriving meanwhile joins the pair instead and the kept candidates
  // are gated against it. Buildings with symmetric floors (the simulator's offices) make
  // whole sets of matches agree on a turned copy of the place; a direct encounter does not.
  double first_join_hold_s = 30.0;
  // A first join's hypothesis is refused when, each candidate of the joining set drawn by its
  // own match with both trajectories' keyframes within join_check_radius_m of its places
  // (rays cut at join_check_range_m: a small heading error moves far walls by more than the
  // margin), more than join_max_conflict of each side's end points land in space the other
  // side's rays saw free (server/join_free_space.h; summed over the set, the smaller side).
  // Measured: ACES 3 robots simultaneous, the aliased T-junction 0.075 (joined there 10-50 m
  // off before); its true joins 0.015 and 0.008; the simulator's tests' true joins 0.000-0.001;
  // twin corridors offered as one 0.057. With the best match's pose for the whole set (a
  // variant), the true joins of Intel, FR079 and ACES (2s, 3s) measured 0.001-0.028.
  double join_check_radius_m = 5.0;
  double join_check_range_m = 8.0;
  double join_max_conflict = 0.05;
  // A candidate whose own maps agree (map-verified): drawn by its own match as above, at most
  // verify_max_conflict of both sides' end points together land in space the other side saw
  // free, out of at least verify_min_points on each side. Two map-verified candidates
  // confirm each other through the pairwise test with each trajectory's estimate between
  // them widened by verify_drift_per_m (x, y) and verify_drift_rad_per_m (heading) per metre
  // its odometry drove between them (the near search's drift rates): the smoother's
  // covariance trusts scan-matched odometry too much. ACES split in two sequentially: the true
  // candidates of R2's visits 80-130 m apart disagreed through R2's estimate by 0.1 rad at
  // sigma 0.01 and through R1's by 1.3 m at sigma 0.2 (chi-square 23-40; 7.2 with the drift);
  // the 180-degree aliases that agree among themselves fail their own maps (pooled 0.069 and
  // more, the true ones 0.011-0.028; on Intel and FR079 split sequentially, false candidates
  // 0.039-0.047 with fewer than 2000 points on a side, true ones 0.000-0.043).
  double verify_max_conflict = 0.045;
  int verify_min_points = 2000;
  double verify_drift_per_m = 0.01;
  double verify_drift_rad_per_m = 0.001;
  // ... and their heading by verify_drift_rad_per_rad per radian the estimate turned between
  // them: scan-matched odometry turning on the spot drives little but its heading errs with the
  // turn (ACES split in three sequentially: R1 turned 2.97 rad between its keyframes 5 and 25,
  // its estimate 0.015 rad off at sigma 0.005; the two true candidates there, plain chi-square
  // 37.2, 27.9 with the per-metre drift alone).
  double verify_drift_rad_per_rad = 0.01;
  // Guided global search, once the target's group holds two trajectories or more: a keyframe's
  // max_global_per_keyframe submaps of the group are, instead of the next ones in turn, those
  // nearest (within guide_max_distance_m) where the kept candidate of the querying trajectory
  // against that group whose own maps agree best (verify_max_conflict, at least
  // guide_min_points on the fewer side; measured once, when offered) puts the keyframe, in the
  // group's trajectory with the nearest one (not the one searched least); the next ones in turn
  // if fewer are near. The cost is the same. ACES split in three sequentially: from
  // R2[65]-R3[135] (0.02 m off, conflict 0.013, 3391 points) the first submap alone, in R1 and
  // R2 by turns, found nothing R3 could join by (R3[235], [245], [255] searched R2 40 m away
  // while R3 passed R1[115], and R3[240] took R1[125], a 180-degree alias, not R1[115]); taking
  // the group's nearest trajectory and its two nearest submaps found R1[115]-R3[225] and
  // R1[125]-R3[235] (0.01 and 0.14 m off), and R3 joined by them.
  int guide_min_points = 1000;
  double guide_max_distance_m = 8.0;
  // Looking back when groups change: when trajectory X comes into one frame with Y, a
  // trajectory Q outside their frame may have passed Y's places before, when nothing could
  // guide a search there (ACES split in three simultaneously: R3 passed R1's places at 400-460
  // s, before R1 and R2 joined at 481 s, and its one true candidate, R2[65]-R3[135], kept no
  // partner). Q's hypothesis against X (its kept candidate whose own maps agree best, as the
  // guided search takes) then places Q's past keyframes in the group's frame: those it puts
  // within near_distance_m of a submap of Y, plus 3 sigma of the drift of both paths from the
  // hypothesis's keyframes (near_drift_*, up to near_wide_max_window_m), are searched globally
  // in that submap, nearest first, the (Q, Y) pairs by turns, at most look_back_max_per_change
  // per group change (0: never), outside the global searches' budget: groups only merge, so a
  // run makes at most look_back_max_per_change x (trajectories - 1) of them (the simulated 100
  // robots x 180 s: 32). The hypothesis picks the submap, not the pose in it: a match is a
  // candidate like any global search's (the same bars, verification, pairwise consistency and
  // gates). ACES split in three simultaneously: R3[237] matched R1[125] (conflict 0.024) and
  // joined R3 with R2[65]-R3[135].
  int look_back_max_per_change = 16;
  FreeSpaceOptions free_space;
  // Joined trajectories: window search near the prediction.
  double near_distance_m = 4.0;
  double near_min_overlap = 0.85;
  double near_min_score = 0.5;
  int near_cooldown_keyframes = 3;
  // The nearest submap is looked up in a grid of each trajectory's submap centres (in its
  // own frame), not among all of them: the positions are refreshed every
  // near_index_refresh_s of data time and at every group merge, and a submap that moved
  // less than near_index_slack_m since is found as before.
  double near_index_refresh_s = 1.0;
  double near_index_slack_m = 1.0;
  double gate_chi2 = 11.34;  // 3 dof, 99 %
  double min_window_m = 0.4;
  double max_window_m = 2.0;
  // Joined trajectories whose estimate drifted apart: when 3 sigma of the prediction exceeds
  // max_window_m, the window grows to 3 sigma up to near_wide_max_window_m (0: never) and
  // its match is gated with the prediction's covariance widened in every direction by its
  // largest translational sigma (ACES 2 robots simultaneous: the true matches of a place
  // R1 saw at 683 s and R2 at 1181 s lay 1.6 m and 3.9 m off along axes of 1-sigma 1.5 and
  // 0.64 m, chi-square 54-63 against the estimate itself). Such a match is held until a
  // second one of the same pair of trajectories, near_pair_min_gap or more query keyframes
  // away (at most near_pair_max_gap), agrees with it through both trajectories' estimates
  // (the pairwise test, pcm_chi2); then both enter. A lone wide match (a wrong place the
  // wider window and gate let through) enters nothing.
  double near_wide_max_window_m = 6.0;
  // Joined trajectories drift apart with the path both robots drove since the nearest
  // constraint that ties them (TrajectoryTies::ShortestDrive, through a third trajectory
  // too): the smoother's covariance trusts scan-matched odometry too much. This drift is
  // added to the prediction's covariance (translation and heading) for the window, and a
  // match the plain gate refuses but the drifted one accepts is held for the pair rule above,
  // like a wide one (0 and 0: no drift term).
  double near_drift_per_m = 0.01;
  double near_drift_rad_per_m = 0.001;
  // When two trajectories come into one frame, their keyframes examined before are
  // near-searched against each other once (every near_catch_up_every-th; 0: never): a place
  // both passed before the join is otherwise never matched (ACES 2 robots simultaneous: R1
  // 456-511 s and R2's 1041-1080 s pass, joined at R1's 650 s, 2 m apart in the map).
  int near_catch_up_every = 1;
  // Saturation (issue 12: the work per keyframe must not grow with the team and the map). A
  // pair already tied near here needs no further match here: the near search is skipped when
  // the shortest drive from the query keyframe to the other's nearest submap through the ties
  // (TrajectoryTies::ShortestDrive: both robots' paths, through a third trajectory too) is
  // under near_saturation_m (0: never skipped). Ties then come every few metres of path
  // instead of every near_cooldown_keyframes keyframes, where each pair of 100 robots met.
  double near_saturation_m = 4.0;
  // At most this many joined trajectories are near-searched per keyframe (0: all), nearest
  // submap first (ties by trajectory id): in a crowd the others are searched at the next
  // keyframes, and the cost per keyframe is bounded whatever the team.
  int near_max_partners = 3;
  int near_pair_min_gap = 2;
  int near_pair_max_gap = 60;
  int near_max_held = 8;  // wide matches held per pair of trajectories
  double min_window_rad = 0.2;
  double max_window_rad = 0.6;
  // Added to the matcher's covariance: submaps are drawn at estimated poses.
  double floor_sigma_m = 0.02;
  double floor_sigma_rad = 0.005;
  int max_waiting = 200;
  ScanReferenceOptions reference{0.05, 0.05, 0.5, 7};
  // The submaps' references built for searches, kept under a memory budget (a submap's
  // drawing never changes: a reference built again has the same bits).
  SubmapCacheOptions submap_cache;
  // The near searches per second of data, whole team (server/match_budget.h; one search, one
  // unit). Not the catch-up of a pair that came into one frame (once per pair), nor the
  // global searches (global_budget).
  MatchBudgetOptions near_budget{20.0, 60.0};
  MatchOptions match;

  Status Validate() const;
};

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

// A candidate encounter: keyframe b measured in the frame of keyframe a.
struct EncounterCandidate {
  PoseKey a;
  PoseKey b;
  Pose2 T_a_b;
  Eigen::Matrix3d covariance = Eigen::Matrix3d::Identity();
  int64_t utime = 0;
  // The keyframe whose scan was the query (b unless the candidate was turned round): two
  // candidates from one query scan are one piece of evidence, not two.
  bool a_is_query = false;
  PoseKey query() const { return a_is_query ? a : b; }
};

class ScanEncounters : public EncounterSource {
 public:
  // Without a pool, matches run on the caller's thread and are used at once.
  explicit ScanEncounters(const ScanEncounterOptions& options = {}, MatchPool* pool = nullptr,
                          MatchSchedule schedule = {})
      : options_(options),
        pool_(pool),
        schedule_(schedule),
        global_queue_(options.global_budget),
        references_(options.submap_cache, options.max_range_m, options.reference),
        near_budget_(options.near_budget) {}

  std::string name() const override { return "scan"; }
  void OnKeyframeAdded(PoseKey key, const GraphView& graph, EncounterSourceOutput* out) override;
  void Poll(int64_t now_utime, const GraphView& graph, EncounterSourceOutput* out) override;
  void Flush(const GraphView& graph, EncounterSourceOutput* out) override;
  size_t pending() const override {
    return waiting_.size() + matches_.size() + global_queue_.waiting();
  }
  std::string StatsLine() const override;
  const CandidateStats& stats() const { return stats_; }
  int64_t joins_contradicted() const { return joins_contradicted_; }
  int64_t near_saturated() const { return near_saturated_; }
  int64_t near_capped() const { return near_capped_; }
  int64_t look_backs() const { return look_backs_; }
  const GlobalSearchQueue& global_searches() const { return global_queue_; }
  const MatchBudget& near_budget() const { return near_budget_; }

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
  // Drawn when its keyframes are solved, built when a search uses it (references_: the
  // same bits as building it at once; most submaps of a large team are never searched).
  struct Submap {
    PoseKey center;
    SubmapDrawing drawing;
  };
  std::shared_ptr<const ScanReference> Reference(const Submap& submap, const GraphView& graph);
  using Pair = std::pair<TrajectoryId, TrajectoryId>;  // (smaller, larger) solver id

  void Examine(const GraphView& graph, EncounterSourceOutput* out);
  void BuildSubmaps(const GraphView& graph);
  // `near_too`: its near searches too (else only its global search, which has its own
  // budget). Returns the near searches submitted.
  int ExamineKeyframe(PoseKey key, const GraphView& graph, bool near_too);
  // Serves the keyframes waiting for a global search while the budget lasts.
  void ServeGlobalQueue(const GraphView& graph);
  // A trajectory a global search of a keyframe takes, and its submaps a kept hypothesis guides
  // the search to (GuidedSubmaps, at most GlobalTries of them; none: the next ones in turn).
  struct GlobalTarget {
    TrajectoryId other;
    std::vector<size_t> guided;
  };
  // The trajectories `key` is searched against: one of each other group (the pair
  // searched least so far), at most max_global_groups_per_keyframe groups.
  std::vector<GlobalTarget> GlobalTargets(PoseKey key, const GraphView& graph) const;
  // The submaps of `other` one keyframe's global search takes (max_global_per_keyframe).
  size_t GlobalTries(TrajectoryId other) const;
  // Submits the searches of `key` against the target's submaps; returns how many.
  int SearchGlobally(PoseKey key, const GlobalTarget& target, const GraphView& graph);
  // The submap of `other` a near search of `key` would match against: the nearest one within
  // near_distance_m, unless the pair is quiet or saturated there (nullopt then).
  struct NearTarget {
    TrajectoryId other;
    size_t submap = 0;  // in submaps_[other]
    double distance = 0.0;
  };
  std::optional<NearTarget> FindNear(PoseKey key, TrajectoryId other, const GraphView& graph);
  // True when a match was submitted.
  bool SearchNear(PoseKey key, const NearTarget& target, const GraphView& graph);
  // True when the pair is tied within near_saturation_m of drive between `key` and `center`.
  bool Saturated(PoseKey key, PoseKey center, const GraphView& graph);
  // The path `key`'s odometry drove from its trajectory's first keyframe (0 without its record).
  double DrivenTo(PoseKey key, const GraphView& graph);
  // Each record's frame (its solver id, FrameOf), in the table's order.
  using TrajectoryFrames = std::vector<std::pair<TrajectoryId, TrajectoryFrame>>;
  static TrajectoryFrames FramesOf(const GraphView& graph);
  // Near-searches the keyframes examined before a pair came into one frame (once per pair).
  void CatchUpJoined(const TrajectoryFrames& frames, const GraphView& graph);
  // When groups changed since the last call: the look back (look_back_max_per_change).
  void LookBackOnGroupChange(const TrajectoryFrames& frames, const GraphView& graph);
  // A past keyframe of a trajectory outside a group to search in a submap of the group.
  struct LookBack {
    double distance = 0.0;  // from where the hypothesis puts the keyframe to the submap's centre
    PoseKey key;
    TrajectoryId other;
    size_t submap = 0;  // in submaps_[other]
  };
  // The past keyframes of `hypothesis`'s querying trajectory that it puts within reach of a
  // submap of `other` (a trajectory of the hypothesis's group), each with its nearest submap.
  std::vector<LookBack> LookBacks(const EncounterCandidate& hypothesis, TrajectoryId other,
                                  const GraphView& graph);
  // Hands a match of keyframe `key` against the submap around `center` to the pool (used
  // lag_s after key_utime, or after `due_from_utime` when given: a past keyframe's).
  void Submit(PoseKey key, PoseKey center, bool global, bool wide, int64_t key_utime,
              MatchPool::Job job, std::optional<int64_t> due_from_utime = std::nullopt);

  // Uses the matches due now (all when `all`), in the order they were made.
  void UseMatches(bool all, const GraphView& graph, EncounterSourceOutput* out);
  // Kept candidates of pairs that came into one frame: gated against the estimate.
  void ResolveKept(const GraphView& graph, EncounterSourceOutput* out);
  // Joins the qualified pairs whose hold ran out (all of them when `flush`).
  void JoinQualified(bool flush, const GraphView& graph, EncounterSourceOutput* out);
  // True when the chi-square gate against the estimate accepts `candidate` (a refusal is
  // counted); `widened`: the prediction's covariance widened in every direction by its largest
  // translational sigma (the wide near search's matches).
  bool PassesGate(const EncounterCandidate& candidate, const GraphView& graph, bool widened);
  // The same test, not counted; `drift` is added to the prediction's covariance.
  bool WithinGate(const EncounterCandidate& candidate, const GraphView& graph, bool widened,
                  const Eigen::Matrix3d& drift) const;
  // Holds a match accepted only by a widened gate until a second one agrees; both enter then.
  void HoldForPair(const EncounterCandidate& candidate, const GraphView& graph,
                   EncounterSourceOutput* out);
  // True when the gate against the estimate accepts it (counts either way).
  bool GateAndEmit(const EncounterCandidate& candidate, const GraphView& graph,
                   EncounterSourceOutput* out);
  void Emit(const EncounterCandidate& candidate, EncounterSourceOutput* out);
  // Pairwise consistency of two candidates of one pair (both oriented a in pair.first).
  // `drift`: each trajectory's estimate between the two widened by the verify_drift_* terms
  // (two map-verified candidates).
  bool Consistent(const EncounterCandidate& c1, const EncounterCandidate& c2,
                  const GraphView& graph, bool drift);
  // The pairwise test's statistic (+inf when a relative pose is not known).
  double PairwiseChi2(const EncounterCandidate& c1, const EncounterCandidate& c2,
                      const GraphView& graph, double drift_per_m, double drift_rad_per_m,
                      double drift_rad_per_rad = 0.0);
  // The free-space conflict of the candidate's own maps (both sides within
  // join_check_radius_m of its places, drawn by its match).
  JoinConflict OwnMapsConflict(const EncounterCandidate& candidate, const GraphView& graph) const;
  // Its own maps agree (verify_max_conflict, verify_min_points).
  bool MapsAgree(const JoinConflict& conflict) const;
  // Two candidates, oriented alike, at two places (Apart) of both sides, seeing other walls at
  // one side at least (pcm_max_shared_view): only then can one confirm the other. A side is
  // one trajectory for two candidates of one pair, or a group of two for two pairs between
  // the same groups (IndependentAcross).
  bool TwoPlaces(const EncounterCandidate& c1, const EncounterCandidate& c2,
                 const GraphView& graph) const;
  // Two keyframes of one group at two places: in one trajectory pcm_min_separation keyframes
  // and pcm_min_separation_m apart in its frame; in two, pcm_min_separation_m apart in the
  // group's frame (the places TwoPlaces and IndependentAcross compare).
  bool Apart(PoseKey x, PoseKey y, const GraphView& graph) const;
  // The share of their views the two keyframes have in common (KeyframeOverlap, in the
  // trajectory's or the group's frame); 1 when a record is missing (no evidence of other walls).
  double SharedView(PoseKey x, PoseKey y, const GraphView& graph) const;

  // Keyframes of one trajectory whose submaps share no keyframe, apart by TwoPlaces' bars and
  // seeing other walls (pcm_max_shared_view).
  bool ApartAndSeeingOtherWalls(PoseKey k1, PoseKey k2, const GraphView& graph) const;

  struct PendingMatch {
    int64_t due_utime = 0;
    PoseKey key;     // the query keyframe
    PoseKey center;  // the other trajectory's submap
    bool global = false;
    bool wide = false;  // a near search's window wider than max_window_m
    int64_t key_utime = 0;
    std::shared_future<std::optional<MatchResult>> result;
  };

  ScanEncounterOptions options_;
  MatchPool* pool_;
  MatchSchedule schedule_;
  std::deque<PendingMatch> matches_;
  std::deque<PoseKey> waiting_;
  std::map<TrajectoryId, std::vector<Submap>> submaps_;
  std::map<Pair, size_t> global_cursor_;
  GlobalSearchQueue global_queue_;
  SubmapCache references_;
  struct Kept {
    EncounterCandidate candidate;
    int support = 0;  // later candidates consistent with it (at other places)
    // Localised in every direction, and not in a hypothesis the free-space test refused:
    // only these take part in a first join.
    bool localised = true;
    // Its own maps agree (MapsAgree, at the estimate it was offered at).
    bool verified = false;
    // The free-space conflict of its own maps measured then (pooled fraction, the fewer
    // side's points; 1 and 0 when not measured: not localised): what guides a global search.
    double conflict = 1.0;
    int64_t conflict_points = 0;
  };
  bool Localised(const EncounterCandidate& candidate) const;
  // Two kept candidates are independent evidence: at two places (TwoPlaces), or, both
  // map-verified, two query scans that are two looks (pcm_max_shared_look) matched against
  // stretches of the other trajectory that share no keyframe and see other walls (one place
  // of the querying robot, seen twice by the other).
  bool Independent(const Kept& k1, const Kept& k2, const GraphView& graph) const;
  // Across two pairs of trajectories between the same two groups (R1-R3 and R2-R3, R1 and R2
  // joined): both candidates map-verified and localised, at two places of both groups
  // (TwoPlaces).
  bool IndependentAcross(const Kept& k1, const Kept& k2, const GraphView& graph) const;
  // Pairwise consistency across two pairs (as above), each side's relative pose predicted by
  // its group's joint estimate, widened by the verify_drift_* terms for the turn between the two
  // keyframes and, within one trajectory, for its drive (a side in two trajectories rests on
  // their ties, not on odometry alone: no drive term).
  bool ConsistentAcross(const EncounterCandidate& c1, const EncounterCandidate& c2,
                        const GraphView& graph);
  // The pairs of trajectories, other than `pair`, between the same two groups as `pair` (their
  // kept candidates may confirm `pair`'s across the pairs).
  std::vector<Pair> PairsBetweenTheSameGroups(const Pair& pair, const GraphView& graph) const;
  // The kept candidate of `query`'s trajectory against a trajectory `accept` takes (of a group
  // the query's is not in) whose own maps agree best (guide_min_points, verify_max_conflict;
  // measured once, when offered), if any.
  const Kept* BestHypothesis(TrajectoryId query,
                             const std::function<bool(TrajectoryId)>& accept) const;
  // The submaps of `other` (at most `most`, nearest first) a global search of `key` is guided
  // to (guide_*), if any; `nearest_m`: the first one's centre from where the hypothesis puts key.
  std::vector<size_t> GuidedSubmaps(PoseKey key, TrajectoryId other, const GraphView& graph,
                                    size_t most, double* nearest_m = nullptr) const;
  // The submaps of `submaps` (at most `most`, nearest first) within guide_max_distance_m of
  // where `hypothesis` (a candidate of key's trajectory against their group) puts key.
  std::vector<size_t> GuidedByHypothesis(PoseKey key, const EncounterCandidate& hypothesis,
                                         const std::vector<Submap>& submaps, const GraphView& graph,
                                         size_t most, double* nearest_m = nullptr) const;
  // The free-space test of the hypothesis of `set` (its first member the best supported).
  bool MapsContradict(const std::vector<Kept*>& set, const GraphView& graph) const;
  // First-join hypotheses refused by the free-space test. Not in snapshots (CandidateStats'
  // format is fixed there): a restored source counts from 0.
  int64_t joins_contradicted_ = 0;
  // Near searches skipped as saturated, and beyond near_max_partners (counts only, like
  // joins_contradicted_: not in snapshots).
  int64_t near_saturated_ = 0;
  int64_t near_capped_ = 0;
  std::map<Pair, std::deque<Kept>> kept_;
  std::map<Pair, int64_t> qualified_since_;  // data time a consistent set first qualified
  int64_t now_utime_ = 0;
  std::map<Pair, int32_t> near_quiet_until_;                  // keyed (examined trajectory, other)
  std::map<Pair, std::deque<EncounterCandidate>> near_held_;  // keyed as near_quiet_until_
  // Per trajectory, its submaps' centres in its frame (items: positions in submaps_).
  struct SubmapIndex {
    PositionIndex index{4.0};
    size_t indexed = 0;  // submaps in the index
    int64_t refreshed_utime = 0;
    int64_t merges = -1;  // the smoother's merge count at the refresh
  };
  // The index of `other`'s submaps, refreshed when due.
  const PositionIndex& NearIndex(TrajectoryId other, const GraphView& graph);
  std::map<TrajectoryId, SubmapIndex> near_index_;
  DrivenPath driven_;  // a function of the table, so not in snapshots
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
  // The same at the last LookBackOnGroupChange, which looks back only for the trajectories
  // newly in one frame since (a cache, not in snapshots: after ImportState the first call
  // only records them).
  TrajectoryFrames looked_back_frames_;
  int64_t look_backs_ = 0;  // searches submitted (a count, not in snapshots)
  CandidateStats stats_;
};

}  // namespace anchormap
