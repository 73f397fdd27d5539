#pragma once
// Looking back when groups change (issue 11): when trajectory X comes into one frame with Y, a
// trajectory Q outside their frame may have passed Y's places before, when nothing could guide
// a search there. Q's best hypothesis against X (JoinQualifier::BestHypothesis: its kept
// candidate whose own maps agree best) then places Q's past keyframes in the group's frame:
// those it puts within near_distance_m of a submap of Y, plus 3 sigma of the drift of both paths
// from the hypothesis's keyframes (NearSearch's drift terms, up to near_wide_max_window_m), are
// searched globally in that submap, nearest first, the (Q, Y) pairs by turns, at most
// look_back_max_per_change per group change, outside the global searches' budget. The matches
// are candidates like any global search's. The options and the measurements behind them:
// server/scan_encounter_options.h.

#include <cstddef>
#include <cstdint>
#include <deque>
#include <vector>

#include "common/solver/keys.h"
#include "server/driven_path.h"
#include "server/encounter_candidate.h"
#include "server/encounter_matches.h"
#include "server/encounter_source.h"
#include "server/encounter_submaps.h"
#include "server/join_qualifier.h"
#include "server/near_search.h"
#include "server/relative_pose.h"
#include "server/scan_encounter_options.h"

namespace anchormap {

class LookBackPlanner {
 public:
  // The other arguments are the scan encounters' parts: the hypotheses come from `qualifier`,
  // the drift terms from `near`, the searches go to `matches`.
  LookBackPlanner(const ScanEncounterOptions& options, DrivenPath* driven,
                  EncounterSubmaps* submaps, const JoinQualifier* qualifier, NearSearch* near,
                  EncounterMatches* matches)
      : options_(options),
        driven_(driven),
        submaps_(submaps),
        qualifier_(qualifier),
        near_(near),
        matches_(matches) {}

  // When groups changed since the last call (`frames`, FramesOf): the look back, but for the
  // keyframes waiting to be examined (`waiting_keys`); the matches are due after `now_utime`.
  void LookBackOnGroupChange(const TrajectoryFrames& frames,
                             const std::deque<PoseKey>& waiting_keys, int64_t now_utime,
                             const GraphView& graph);
  // Restored from a snapshot: the next call only records the frames.
  void Forget() { looked_back_frames_.clear(); }
  int64_t look_backs() const { return look_backs_; }

 private:
  using Submap = EncounterSubmaps::Submap;
  // A past keyframe of a trajectory outside a group to search in a submap of the group.
  struct LookBack {
    double distance = 0.0;  // from where the hypothesis puts the keyframe to the submap's centre
    PoseKey key;
    TrajectoryId other;
    size_t submap = 0;  // in the submaps of `other`
  };
  // The past keyframes of `hypothesis`'s querying trajectory that it puts within reach of a
  // submap of `other` (a trajectory of the hypothesis's group), each with its nearest submap.
  std::vector<LookBack> LookBacks(const EncounterCandidate& hypothesis, TrajectoryId other,
                                  const std::deque<PoseKey>& waiting_keys, const GraphView& graph);

  ScanEncounterOptions options_;
  DrivenPath* driven_;
  EncounterSubmaps* submaps_;
  const JoinQualifier* qualifier_;
  NearSearch* near_;
  EncounterMatches* matches_;
  // The frames at the last LookBackOnGroupChange, which looks back only for the trajectories
  // newly in one frame since (a cache, not in snapshots: after ImportState the first call
  // only records them).
  TrajectoryFrames looked_back_frames_;
  int64_t look_backs_ = 0;  // searches submitted (a count, not in snapshots)
};

}  // namespace anchormap
