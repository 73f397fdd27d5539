#pragma once
// Loop closures within a trajectory found by scan matching (issue 11, item 3). A keyframe
// is examined once the smoother has solved it (one update after it arrived):
//   1. candidates: earlier keyframes of its trajectory, at least min_index_gap back, whose
//      predicted position may lie within max_distance_m of it: the Mahalanobis distance of
//      the predicted offset from that disc, under the joint covariance of the two poses
//      (PredictRelativePose), below candidate_chi2; the nearest max_candidates (optionally not
//      those an entered closure already ties to the keyframe's stretch of path: saturation_m);
//   2. verification: the keyframe's scan matched against a submap of the candidate's
//      neighbours (KeyframeSubmap) in a window around the prediction sized by its
//      covariance; a good match has score >= min_score and overlap >= min_overlap;
//   3. a chi-square gate of the match against the prediction (both covariances) before it
//      enters the graph as a between factor (kind kLoopClosure).
// Across large drift (a long loop: 3 sigma of the prediction beyond the window bounds), the
// local window cannot hold the true pose. Such a "wide" candidate is searched by branch and
// bound over wide_sigmas of the prediction (capped) against a larger submap, at most one per
// wide_every_keyframes keyframes of a trajectory; a wrong closure of that size would ruin the
// map, so a wide match passes higher bars and is only kept as a hypothesis: it enters the
// graph with a later wide match of the same trajectory, from a query at least
// wide_pair_min_gap keyframes on, that agrees with it through the estimate (pairwise
// consistency, PairwiseInconsistency2). A wide match whose overlap is below wide_min_overlap
// but at least wide_weak_min_overlap (on ACES the long loops' returns overlap 0.69-0.80: the
// robot comes back along the other side of the corridor) is kept too, as a weak hypothesis:
// it enters only with a strong one (two weak matches of a look-alike 8 m away agreed in the
// simulated periodic corridor) whose query stands wide_pair_min_separation_m from its own, so
// that the two are two views of the loop's far end, not one spot matched twice, and whose
// match pins the place in every direction (largest standard deviation at most
// wide_weak_partner_max_sigma_m): a corridor match, free along the corridor (sigma 0.4-0.5 m),
// agrees with any slide of the weak one along it (on Intel a weak match 0.25 m off entered
// so and bent the map). A wide
// match is refined against the keyframes near where the query looks (refine_look_ahead_m in
// front of it), not where it stands: with a 180-degree laser the keyframe nearest to the
// query's position may have passed it facing the other way; of the keyframes looking there
// (refine_choice_radius_m), the one whose own scan the query matches best: the place submap draws
// every pass at its estimate, and an open loop draws two passes of a place metres apart.
// A wide window can hold a look-alike of
// the place (the simulator's offices repeat every 8 m: a window of 3 sigma of the drift model
// reached the copy, and two queries agreed on it): the query is also matched in the local window
// around the prediction (the "rival"), and when that match agrees with the estimate's own
// covariance (without the drift model) at a pose distinct from the wide match's, the estimate
// is borne out where it is and the wide match is refused (counted in gate and as "ambiguous").
// The rival can check the estimate only where the map has been: a wide pair enters only when
// the estimate puts one of its queries within max_distance_m of an older keyframe. A place
// reached for the first time can match a look-alike of it in the window, and two such matches
// agree (the periodic corridor's north end matched the south corridor's, 10 m away).
// The keyframes examined are bounded by a matching budget per second of data, whole team
// (`budget`, server/match_budget.h): with many robots, those whose trajectory drove farthest
// since its last examined keyframe go first, and the rest are not examined.
// Step 2 runs on the MatchPool's workers (or on the caller's thread without a pool); step 3
// and what follows from it happen when the canonical input reaches the keyframe's time plus
// the schedule's lag (MatchSchedule), waiting for the match if needed: the results do not
// depend on thread timing or the number of workers.

#include <cstdint>
#include <deque>
#include <future>
#include <map>
#include <memory>
#include <optional>
#include <set>
#include <string>
#include <utility>
#include <vector>

#include "common/geometry/angle.h"
#include "common/scan_matching/correlative_matcher.h"
#include "common/scan_matching/scan_reference.h"
#include "common/util/status.h"
#include "server/candidate_stats.h"
#include "server/driven_path.h"
#include "server/encounter_source.h"
#include "server/loop_closure_state.h"
#include "server/match_budget.h"
#include "server/match_pool.h"
#include "server/relative_pose.h"
#include "server/submap_cache.h"
#include "server/trajectory_table.h"

namespace anchormap {

struct LoopClosureOptions {
  int min_index_gap = 20;        // keyframes between the two ends of a closure
  double max_distance_m = 4.0;   // a candidate may be this close to the keyframe
  double candidate_chi2 = 9.21;  // 2 dof, 99 %: the gate on the predicted offset
  double gate_chi2 = 11.34;      // 3 dof, 99 %: the gate on the match
  int max_candidates = 2;        // per keyframe
  int cooldown_keyframes = 3;    // keyframes skipped after a closure in the trajectory
  // Saturation (issue 12): a candidate is not matched when a closure already entered ties
  // this place to that one, both ends within this much path (odometry) of the keyframe's and
  // the candidate's (0: never skipped). A robot driving along its old path then closes every
  // few metres instead of every cooldown_keyframes + 1 keyframes. The wide search is not
  // affected: it looks for the places the estimate has lost. Off by default: with 2 m and the
  // near search's saturation together, Intel split in three (simultaneous) went 0.0234 ->
  // 0.0342 m (0.0238 with this off, 0.0234 with the near search's off); aces-1 measured
  // 0.0424 at 2 m, 0.0431 at 3 m. A skipped candidate hands its slot to the next nearest, so
  // the matches run fall less than the skips (100 x 60: 1211 skipped, candidates 838 -> 766).
  double saturation_m = 0.0;
  // Neighbours on each side of the candidate in its reference (0: its scan alone). A submap
  // drawn at raw-odometry estimates is less exact than one scan: on the simulated loop the
  // worst closure was 3 mm with one scan, 0.11 m with 2 neighbours each side.
  int submap_half_width = 0;
  double max_range_m = 15.0;  // points farther from the robot are not used
  double min_score = 0.5;
  double min_overlap = 0.7;
  // The search window: 3 sigma of the prediction, within these bounds.
  double min_window_m = 0.4;
  double max_window_m = 2.0;
  double min_window_rad = 0.2;
  double max_window_rad = 0.6;
  // Added to the matcher's covariance: the submap is drawn at estimated poses.
  double floor_sigma_m = 0.02;
  double floor_sigma_rad = 0.005;
  int max_waiting = 200;  // keyframes waiting to be solved; the oldest is dropped beyond
  // Wide candidates (see the top of this file).
  bool wide_search = true;
  // Drift the estimate's covariance may not hold, per metre of path between the two ends
  // (scan-matched odometry is overconfident): added to the wide search's prediction.
  double drift_per_m = 0.03;
  double drift_rad_per_m = 0.002;
  // No wide search this soon after an accepted closure (0: no pause). None by default: a
  // closure corrects the estimate where it closed, not the other passes the robot reaches next
  // (ACES 1266-1290 s: the return closed on its 1018 s pass, then 8 keyframes on drove over its
  // 1109 s pass, 2 m off in the estimate; a pause of 20 never searched it: aces-1 0.064 m with
  // 20, 0.058 with 10, 0.043 with 5 and 0; fr079-3s 0.0529 with 20 and 0, 0.0535 with 5).
  int wide_quiet_keyframes = 0;
  double wide_sigmas = 3.0;
  double wide_max_window_m = 12.0;
  double wide_max_window_rad = 0.8;
  int wide_submap_half_width = 10;
  // EXPERIMENT: the wide submap by place (DrawKeyframeSubmapNear) instead of +-half width by
  // index: the keyframes within the window (plus max_distance_m) of the predicted pose.
  bool wide_submap_by_place = true;
  bool wide_submap_place_keeps_index = true;  // the +-half width by index, then by place
  int wide_submap_max_keyframes = 21;
  double wide_submap_spacing_m = 0.5;
  double wide_submap_spacing_rad = 0.5;
  int wide_refine_half_width = 2;  // the submap a wide match is refined against
  int wide_every_keyframes = 4;
  double wide_min_score = 0.6;
  double wide_min_overlap = 0.8;
  double wide_pair_chi2 = 11.34;        // 3 dof, 99 %
  int wide_pair_min_gap = 4;            // keyframes between the two queries of a pair, at least...
  int wide_pair_max_gap = 60;           // ... and at most (older hypotheses are given up)
  int wide_max_kept = 8;                // hypotheses kept per trajectory
  double wide_weak_min_overlap = 0.65;  // a weak hypothesis from here (see the top)
  double wide_pair_min_separation_m = 1.0;  // between the queries of a pair with a weak one
  double refine_look_ahead_m = 2.0;         // the point the refinement's keyframe is chosen by
  // Of the keyframes looking within this of that point, the one whose scan the query matches
  // best (0: the nearest one).
  double refine_choice_radius_m = 2.0;
  double wide_weak_partner_max_sigma_m = 0.1;  // a weak one's partner pins the place this well
  ScanReferenceOptions reference{0.05, 0.05, 0.5, 5};
  // The candidates' submaps, kept for the next keyframes (which mostly have the same
  // candidates) under a memory budget.
  SubmapCacheOptions submap_cache;
  // The matching work per second of data, whole team (server/match_budget.h): a local match
  // costs 1 unit, a wide search budget_wide_units (its branch and bound, rival and refinement:
  // ~8 local matches' CPU at 100 robots).
  // 40 units per second bind only with many robots: a 0.5 s solve period brings at most
  // ~6 keyframes at once from the real logs' 1-3 robots (60 units at 10 each, within the
  // burst), while 100 simulated robots ask ~150 units per second.
  MatchBudgetOptions budget{40.0, 120.0};
  double budget_wide_units = 8.0;
  // A wide search's branch and bound costs what it scores: as a map grows, its place submaps
  // hold more passes and more of the window's blocks score above the bar (20 robots: ~0.2 CPU
  // s per search at 630 s of data, ~50 local matches). So once its result is used, a wide
  // search whose scored nodes / budget_wide_nodes_per_unit exceed budget_wide_units pays the
  // difference too (the bucket goes into debt; later tokens repay it): the budget bounds the
  // wide searches' cost, not their number. 0: every wide search costs budget_wide_units.
  double budget_wide_nodes_per_unit = 25000.0;
  MatchOptions match;

  Status Validate() const;
};

// A keyframe of a place submap: its index, its pose in the submap's frame, its scan's reference.
struct SeenKeyframe {
  int32_t index = 0;
  Pose2 T_submap_keyframe;
  std::shared_ptr<const ScanReference> scan;
};
// The keyframe whose own scan `query` matches best (MatchLocal in `window` around the pose the
// submap's drawing gives, T_submap_query); -1 when none matches. A place submap draws every
// pass of the place at its estimate: where an open loop drew two passes apart, a query matched
// on one lies, by the drawing, just as near to keyframes of the other (see RefineWide).
int32_t BestSeenKeyframe(const std::vector<SeenKeyframe>& keyframes, const PointCloud& query,
                         const Pose2& T_submap_query, const LocalMatchOptions& window);

// What a wide hypothesis brings to a pair.
struct WideEvidence {
  bool weak = false;
  double sigma_m = 0.0;  // its match's largest translational standard deviation
};
// The largest translational standard deviation of a match's covariance (x, y, theta).
double LargestTranslationSigma(const Eigen::Matrix3d& covariance);
// Whether two wide hypotheses that agree through the estimate may enter together, their
// queries being `separation_m` apart: a weak match needs a strong partner from another place
// (one spot matched twice is one piece of evidence; two weak matches are not enough) that
// pins the place in every direction (a partner free along a corridor vouches for nothing
// along it).
bool WidePairMayEnter(const WideEvidence& first, const WideEvidence& second, double separation_m,
                      const LoopClosureOptions& options);
// Whether the estimate puts `key` within radius_m of a keyframe of its trajectory at least
// min_index_gap older: in a place the map has been, where the rival match can check the
// estimate (see OfferWide).
bool EstimatedWhereTheMapHasBeen(const Smoother& smoother, PoseKey key, int min_index_gap,
                                 double radius_m);
// The drift model's covariance for a path of `path_m` (drift_per_m, drift_rad_per_m).
Eigen::Matrix3d WideDriftCovariance(double path_m, const LoopClosureOptions& options);
// The gate of a refined wide match (RefineWide): the match against the estimate's prediction
// of the keyframe it ties, with the drift model added for `tied_path_m`, the path from that
// keyframe to the query (not from the keyframe the search was drawn around, which may lie far
// further back: see the test).
struct RefinedWideGate {
  double drift_sigma_m = 0.0;  // the drift model's allowance, 1 sigma per axis
  double chi2 = 0.0;
  bool passes = false;  // chi2 <= gate_chi2
};
RefinedWideGate GateRefinedWide(const PredictedRelativePose& predicted, const Pose2& match,
                                const Eigen::Matrix3d& match_covariance, double tied_path_m,
                                const LoopClosureOptions& options);
// The chi-square inconsistency of two wide closures (first: candidate a1 to query b1
// measured as `first`; second: a2 to b2) through the estimate's relative poses a1-a2
// (`candidates`) and b1-b2 (`queries`). The queries' relative heading is widened by the
// drift model's rotation for the path the robot drove between them (`query_path_m`): the
// estimate of that newest stretch is what a loop not closed yet has bent (ACES, the third
// robot: the 1234 s pass closed on the 1144 s pass and the 1284 s pass on the 1100 s pass,
// both true, 10.6 m of path apart, disagreed by 0.037 rad through an estimate of a few mrad:
// chi-square 14.8 (2.6 widened), the loop stayed open, aces-3s 0.1217 m, 0.0954 widened).
// Translation is not widened (intel-1 0.0239 -> 0.0245 m), nor the candidates' relative pose:
// they may lie far apart along the path (a wide pair 7 m apart then entered: aces-1 0.043 ->
// 0.132 m).
double WidePairInconsistency2(const PredictedRelativePose& candidates, const Pose2& first,
                              const Eigen::Matrix3d& first_covariance,
                              PredictedRelativePose queries, const Pose2& second,
                              const Eigen::Matrix3d& second_covariance, double query_path_m,
                              const LoopClosureOptions& options);

class LoopClosures : public EncounterSource {
 public:
  // Without a pool, matches run on the caller's thread and are used at once (lag 0).
  explicit LoopClosures(const LoopClosureOptions& options = {}, MatchPool* pool = nullptr,
                        MatchSchedule schedule = {})
      : options_(options),
        pool_(pool),
        schedule_(schedule),
        references_(options.submap_cache, options.max_range_m, options.reference),
        budget_(options.budget) {}

  std::string name() const override { return "loop"; }
  void OnKeyframeAdded(PoseKey key, const GraphView& graph, EncounterSourceOutput* out) override;
  void Poll(int64_t now_utime, const GraphView& graph, EncounterSourceOutput* out) override;
  void Flush(const GraphView& graph, EncounterSourceOutput* out) override;
  size_t pending() const override { return waiting_.size() + matches_.size(); }
  std::string StatsLine() const override {
    return stats_.Summary(name()) + " wide " + std::to_string(wide_searches_) + " ambiguous " +
           std::to_string(ambiguous_) + " saturated " + std::to_string(saturated_) +
           " over_budget " + std::to_string(budget_.skipped()) + " folded " +
           std::to_string(folded_) + " " + references_.stats().Summary(name());
  }
  const CandidateStats& stats() const { return stats_; }
  int64_t wide_searches() const { return wide_searches_; }  // of stats().candidates
  int64_t ambiguous() const { return ambiguous_; }          // of stats().gate_rejected
  int64_t saturated() const { return saturated_; }          // candidates not matched
  const MatchBudget& budget() const { return budget_; }
  // Units charged beyond budget_wide_units for wide searches' size (budget_wide_nodes_per_unit).
  double units_by_size() const { return units_by_size_; }

  // The source's state for snapshots (loop_closure_state.h, defined in loop_closure_state.cc):
  // ExportState waits for the matches in flight; ImportState is for a source given no input.
  LoopClosureState ExportState() const;
  void ImportState(const LoopClosureState& state);

 private:
  // The reference of the submap around `center` drawn at the current estimates (cached).
  std::shared_ptr<const ScanReference> Reference(const TrajectoryRecord& record,
                                                 const GraphView& graph, PoseKey center,
                                                 int half_width);
  // Examines the waiting keyframes the smoother has solved.
  void Examine(const GraphView& graph, EncounterSourceOutput* out);
  // Chooses the keyframe's candidates and hands their matches to the pool.
  void ExamineKeyframe(PoseKey key, const GraphView& graph);
  // Uses the matches due at `now_utime` (all when `all`), in the order they were made.
  void UseMatches(int64_t now_utime, bool all, const GraphView& graph, EncounterSourceOutput* out);
  // Charges a wide search's size beyond budget_wide_units (budget_wide_nodes_per_unit).
  void ChargeWideBySize(const LatticeSearchStats& search);
  // Hands one candidate's match to the pool (wide: the branch-and-bound window search).
  // `drift`: added to the prediction's covariance (wide searches, see SubmitWide).
  void Submit(PoseKey candidate, PoseKey key, const PredictedRelativePose& predicted,
              const Eigen::Matrix3d& drift, bool wide, const TrajectoryRecord& record,
              const GraphView& graph, const std::shared_ptr<const PointCloud>& query);
  // The keyframe's wide search, when it is due: against the candidate likeliest under the
  // estimate with the drift model added, when that needs more than the local window.
  void SubmitWide(PoseKey key, const GraphView& graph, const TrajectoryRecord& record,
                  const std::shared_ptr<const PointCloud>& query);
  bool NeedsWideWindow(const Eigen::Matrix3d& covariance) const;
  // True when an entered closure of the trajectory has its ends within saturation_m of path
  // of `key` and of `candidate`.
  bool Saturated(const TrajectoryRecord& record, PoseKey candidate, PoseKey key);

  // A wide match waiting for a consistent second.
  struct Hypothesis {
    PoseKey candidate;
    PoseKey key;
    Pose2 measured;
    Eigen::Matrix3d covariance;
    int64_t key_utime = 0;
    bool weak = false;  // overlap below wide_min_overlap: enters only with a separated second
  };
  // Keeps a wide match, or enters it with an earlier one it agrees with.
  void OfferWide(const Hypothesis& hypothesis, const GraphView& graph, EncounterSourceOutput* out);
  void Emit(const Hypothesis& closure, EncounterSourceOutput* out);

  // A match on its way: what its result is checked against.
  struct PendingMatch {
    int64_t due_utime = 0;
    PoseKey candidate;
    PoseKey key;
    int64_t key_utime = 0;
    PredictedRelativePose predicted;
    bool wide = false;
    Eigen::Matrix3d drift = Eigen::Matrix3d::Zero();  // added to every prediction's covariance
    // Wide only: the query, and the submap's keyframes (index, pose in the candidate's frame).
    std::shared_ptr<const PointCloud> query;
    std::vector<std::pair<int32_t, Pose2>> submap_poses;
    std::shared_future<std::optional<MatchResult>> result;
    // Wide only: the query matched in the local window around the prediction (the rival).
    std::shared_future<std::optional<MatchResult>> rival;
  };
  // True when the rival passes the wide bars at a pose distinct from the wide match's.
  bool Ambiguous(const PendingMatch& pending, const MatchResult& wide) const;
  // A wide match (against a submap drawn at drifting estimates) made exact: the query
  // matched locally against a small submap around the keyframe nearest to where it landed. nullopt
  // (counted) when that match is weak or disagrees with the estimate.
  std::optional<Hypothesis> RefineWide(const PendingMatch& pending, const MatchResult& coarse,
                                       const GraphView& graph);

  LoopClosureOptions options_;
  MatchPool* pool_;
  MatchSchedule schedule_;
  std::deque<PendingMatch> matches_;
  int64_t now_utime_ = 0;
  std::deque<PoseKey> waiting_;
  std::map<TrajectoryId, int32_t> quiet_until_;  // cooldown per trajectory
  std::map<TrajectoryId, int32_t> next_wide_;    // rate limit of wide searches per trajectory
  std::map<TrajectoryId, std::deque<Hypothesis>> kept_;
  std::map<TrajectoryId, int32_t> last_closure_;  // index of the newest closure's keyframe
  // The (candidate, key) index pairs entered, per trajectory: a local match and a confirmed
  // wide one can name the same pair, and one place seen once must count once.
  std::map<TrajectoryId, std::set<std::pair<int32_t, int32_t>>> entered_;
  CandidateStats stats_;
  int64_t folded_ = 0;  // keyframes not searched from: folded onto a node (reduced graph)
  int64_t wide_searches_ = 0;
  SubmapCache references_;
  int64_t ambiguous_ = 0;
  DrivenPath driven_;  // a function of the table, so not in snapshots
  // Candidates skipped as saturated (a count only: not in snapshots, a restored source counts
  // from 0).
  int64_t saturated_ = 0;
  MatchBudget budget_;
  double units_submitted_ = 0.0;  // budget units of the matches submitted so far
  double units_by_size_ = 0.0;    // of them, charged for wide searches' size (not in snapshots)
};

}  // namespace anchormap
