#pragma once
// Loop closures within a trajectory found by scan matching (issue 11, item 3). A keyframe
// is examined once the smoother has solved it (one update after it arrived):
//   1. candidates: earlier keyframes of its trajectory, at least min_index_gap back, whose
//      predicted position may lie within max_distance_m of it: the Mahalanobis distance of
//      the predicted offset from that disc, under the joint covariance of the two poses
//      (PredictRelativePose), below candidate_chi2; the nearest max_candidates;
//   2. verification: the keyframe's scan matched against a submap of the candidate's
//      neighbours (KeyframeSubmap) in a window around the prediction sized by its
//      covariance; a good match has score >= min_score and overlap >= min_overlap;
//   3. a chi-square gate of the match against the prediction (both covariances) before it
//      enters the graph as a between factor (kind kLoopClosure).
// Step 2 runs on the MatchPool's workers (or on the caller's thread without a pool); step 3
// and what follows from it happen when the canonical input reaches the keyframe's time plus
// the schedule's lag (MatchSchedule), waiting for the match if needed: the results do not
// depend on thread timing or the number of workers.

#include <cstdint>
#include <deque>
#include <future>
#include <map>
#include <optional>
#include <string>

#include "common/scan_matching/correlative_matcher.h"
#include "common/scan_matching/scan_reference.h"
#include "common/util/status.h"
#include "server/candidate_stats.h"
#include "server/encounter_source.h"
#include "server/match_pool.h"
#include "server/relative_pose.h"

namespace anchormap {

struct LoopClosureOptions {
  int min_index_gap = 20;        // keyframes between the two ends of a closure
  double max_distance_m = 4.0;   // a candidate may be this close to the keyframe
  double candidate_chi2 = 9.21;  // 2 dof, 99 %: the gate on the predicted offset
  double gate_chi2 = 11.34;      // 3 dof, 99 %: the gate on the match
  int max_candidates = 2;        // per keyframe
  int cooldown_keyframes = 3;    // keyframes skipped after a closure in the trajectory
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
  ScanReferenceOptions reference{0.05, 0.05, 0.5, 5};
  MatchOptions match;

  Status Validate() const;
};

class LoopClosures : public EncounterSource {
 public:
  // Without a pool, matches run on the caller's thread and are used at once (lag 0).
  explicit LoopClosures(const LoopClosureOptions& options = {}, MatchPool* pool = nullptr,
                        MatchSchedule schedule = {})
      : options_(options), pool_(pool), schedule_(schedule) {}

  std::string name() const override { return "loop"; }
  void OnKeyframeAdded(PoseKey key, const GraphView& graph, EncounterSourceOutput* out) override;
  void Poll(int64_t now_utime, const GraphView& graph, EncounterSourceOutput* out) override;
  void Flush(const GraphView& graph, EncounterSourceOutput* out) override;
  size_t pending() const override { return waiting_.size() + matches_.size(); }
  std::string StatsLine() const override { return stats_.Summary(name()); }
  const CandidateStats& stats() const { return stats_; }

 private:
  // Examines the waiting keyframes the smoother has solved.
  void Examine(const GraphView& graph, EncounterSourceOutput* out);
  // Chooses the keyframe's candidates and hands their matches to the pool.
  void ExamineKeyframe(PoseKey key, const GraphView& graph);
  // Uses the matches due at `now_utime` (all when `all`), in the order they were made.
  void UseMatches(int64_t now_utime, bool all, EncounterSourceOutput* out);

  // A match on its way: what its result is checked against.
  struct PendingMatch {
    int64_t due_utime = 0;
    PoseKey candidate;
    PoseKey key;
    int64_t key_utime = 0;
    PredictedRelativePose predicted;
    std::shared_future<std::optional<MatchResult>> result;
  };

  LoopClosureOptions options_;
  MatchPool* pool_;
  MatchSchedule schedule_;
  std::deque<PendingMatch> matches_;
  int64_t now_utime_ = 0;
  std::deque<PoseKey> waiting_;
  std::map<TrajectoryId, int32_t> quiet_until_;  // cooldown per trajectory
  CandidateStats stats_;
};

}  // namespace anchormap
