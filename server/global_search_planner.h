#pragma once
// The global search of trajectories not in one group (issue 11, item 4): every global_every-th
// solved keyframe is searched globally (GlobalSearch: every heading, the submap's whole grid) in
// up to max_global_per_keyframe submaps of one trajectory of each of at most
// max_global_groups_per_keyframe other groups (the pair searched least), within a team-wide
// budget per second of data (GlobalSearchQueue: the cost does not grow with the team). The
// submaps are the next ones in turn, or, once the target's group holds two trajectories or more,
// those nearest where the querying trajectory's best hypothesis against the group puts the
// keyframe (JoinQualifier::BestHypothesis, guide_*), in the group's trajectory nearest it. The
// matches found are candidates for the join qualifier. The options and the measurements behind
// them: server/scan_encounter_options.h.

#include <cstddef>
#include <cstdint>
#include <map>
#include <utility>
#include <vector>

#include "common/solver/keys.h"
#include "server/encounter_candidate.h"
#include "server/encounter_matches.h"
#include "server/encounter_source.h"
#include "server/encounter_submaps.h"
#include "server/global_search_queue.h"
#include "server/join_qualifier.h"
#include "server/scan_encounter_options.h"
#include "server/scan_encounter_state.h"

namespace anchormap {

class GlobalSearchPlanner {
 public:
  // `submaps`, `qualifier` (its hypotheses guide the searches) and `matches` are the scan
  // encounters'.
  GlobalSearchPlanner(const ScanEncounterOptions& options, EncounterSubmaps* submaps,
                      const JoinQualifier* qualifier, EncounterMatches* matches)
      : options_(options),
        submaps_(submaps),
        qualifier_(qualifier),
        matches_(matches),
        global_queue_(options.global_budget) {}

  // The keyframes waiting for their global search, and the budget.
  GlobalSearchQueue& queue() { return global_queue_; }
  const GlobalSearchQueue& queue() const { return global_queue_; }
  // Serves the keyframes waiting for a global search while the budget lasts.
  void ServeGlobalQueue(const GraphView& graph);

  // Snapshots: the cursors and the queue (scan_encounter_state.h).
  void ExportState(ScanEncounterState* s) const;
  void ImportState(const ScanEncounterState& s);

 private:
  using Pair = std::pair<TrajectoryId, TrajectoryId>;
  using Submap = EncounterSubmaps::Submap;
  // A trajectory a global search of a keyframe takes, and its submaps a kept hypothesis guides
  // the search to (GuidedSubmaps, at most GlobalTries of them; none: the next ones in turn).
  struct GlobalTarget {
    TrajectoryId other;
    std::vector<size_t> guided;
  };
  // The trajectories `key` is searched against: one of each other group (the pair
  // searched least so far), at most max_global_groups_per_keyframe groups.
  std::vector<GlobalTarget> GlobalTargets(PoseKey key, const GraphView& graph) const;
  // Whether GlobalTargets(key) is not empty: some other group holds a trajectory with submaps
  // (and max_global_groups_per_keyframe >= 1), found without ranking them.
  bool HasGlobalTarget(PoseKey key, const GraphView& graph) const;
  // Whether GlobalTargets ranks trajectory `id` for `key`: in another group than key's, with
  // submaps.
  bool IsGlobalTarget(PoseKey key, TrajectoryId id, const GraphView& graph) const;
  // The submaps of `other` one keyframe's global search takes (max_global_per_keyframe).
  size_t GlobalTries(TrajectoryId other) const;
  // Submits the searches of `key` against the target's submaps; returns how many.
  int SearchGlobally(PoseKey key, const GlobalTarget& target, const GraphView& graph);
  // The submaps of `other` (at most `most`, nearest first) a global search of `key` is guided
  // to (guide_*), if any; `nearest_m`: the first one's centre from where the hypothesis puts key.
  // `grouped`: another of the table's trajectories is in other's anchored group (none: other
  // is searched in turn).
  std::vector<size_t> GuidedSubmaps(PoseKey key, TrajectoryId other, bool grouped,
                                    const GraphView& graph, size_t most,
                                    double* nearest_m = nullptr) const;
  // The submaps of `submaps` (at most `most`, nearest first) within guide_max_distance_m of
  // where `hypothesis` (a candidate of key's trajectory against their group) puts key.
  std::vector<size_t> GuidedByHypothesis(PoseKey key, const EncounterCandidate& hypothesis,
                                         const std::vector<Submap>& submaps, const GraphView& graph,
                                         size_t most, double* nearest_m = nullptr) const;

  ScanEncounterOptions options_;
  EncounterSubmaps* submaps_;
  const JoinQualifier* qualifier_;
  EncounterMatches* matches_;
  std::map<Pair, size_t> global_cursor_;
  GlobalSearchQueue global_queue_;
};

}  // namespace anchormap
