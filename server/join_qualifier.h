#pragma once
// The first join of two groups by scan matching (issue 11): the candidates between two
// trajectories not in one frame are kept (at most max_kept per pair) and join the pair only
// when two of them at different places agree through each trajectory's own estimate (pairwise
// consistency, Mangelson et al., ICRA 2018), with at least alternative_ratio times the support
// of any kept candidate they disagree with, after first_join_hold_s, and when the maps around
// the matched places do not contradict each other (join_max_conflict). Two map-verified
// candidates (their own maps agree: verify_*) confirm each other with each estimate widened for
// the drive and the turn between them, from one place of one trajectory when they are two looks
// (pcm_max_shared_look), and across two pairs between the same two groups. The kept candidate
// whose own maps agree best is the hypothesis that guides the global search and the look back
// (BestHypothesis). No matching here: it judges what it is offered. The options and the
// measurements behind them: server/scan_encounter_options.h.

#include <cstdint>
#include <deque>
#include <functional>
#include <map>
#include <string>
#include <utility>
#include <vector>

#include "common/solver/keys.h"
#include "server/candidate_stats.h"
#include "server/driven_path.h"
#include "server/encounter_candidate.h"
#include "server/encounter_source.h"
#include "server/join_free_space.h"
#include "server/scan_encounter_options.h"
#include "server/scan_encounter_state.h"

namespace anchormap {

class JoinQualifier {
 public:
  // `stats` and `driven` are the scan encounters' (shared with their other parts); the joining
  // constraints are entered as from `source_name`.
  JoinQualifier(const ScanEncounterOptions& options, CandidateStats* stats, DrivenPath* driven,
                std::string source_name)
      : options_(options), stats_(stats), driven_(driven), source_name_(std::move(source_name)) {}

  // A candidate between two trajectories not in one frame: kept, and its pair qualified (at
  // data time `now_utime`) when it completes a consistent set.
  void Offer(const EncounterCandidate& offered, const GraphView& graph, int64_t now_utime);
  // Joins the qualified pairs whose hold ran out at `now_utime` (all of them when `flush`).
  void JoinQualified(bool flush, int64_t now_utime, const GraphView& graph,
                     EncounterSourceOutput* out);
  // The kept candidates of the pairs that came into one frame by other evidence, taken out (to
  // be gated against the estimate).
  std::vector<EncounterCandidate> TakeJoined(const GraphView& graph);
  // End of input: gives up the kept candidates but those of pairs `constraints` bring into one
  // frame (the server solves the join and flushes once more: TakeJoined then).
  void GiveUpUnlessJoinedBy(const std::vector<EncounterConstraint>& constraints,
                            const GraphView& graph);
  // The kept candidate of `query`'s trajectory against a trajectory `accept` takes (of a group
  // the query's is not in) whose own maps agree best (verify_max_conflict, at least
  // `min_points` on the fewer side; measured once, when offered), if any.
  const EncounterCandidate* BestHypothesis(TrajectoryId query,
                                           const std::function<bool(TrajectoryId)>& accept,
                                           int min_points) const;
  // First-join hypotheses refused by the free-space test.
  int64_t joins_contradicted() const { return joins_contradicted_; }

  // Snapshots: the kept candidates and the qualified pairs (scan_encounter_state.h).
  void ExportState(ScanEncounterState* s) const;
  void ImportState(const ScanEncounterState& s);

 private:
  using Pair = std::pair<TrajectoryId, TrajectoryId>;  // (smaller, larger) solver id
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
  // verify_radius_m of its places, drawn by its match).
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
  // The free-space test of the hypothesis of `set` (its first member the best supported).
  bool MapsContradict(const std::vector<Kept*>& set, const GraphView& graph) const;

  ScanEncounterOptions options_;
  CandidateStats* stats_;
  DrivenPath* driven_;
  std::string source_name_;
  std::map<Pair, std::deque<Kept>> kept_;
  std::map<Pair, int64_t> qualified_since_;  // data time a consistent set first qualified
  // First-join hypotheses refused by the free-space test. Not in snapshots (CandidateStats'
  // format is fixed there): a restored source counts from 0.
  int64_t joins_contradicted_ = 0;
};

}  // namespace anchormap
