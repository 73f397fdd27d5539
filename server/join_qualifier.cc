#include "server/join_qualifier.h"

#include <algorithm>
#include <cmath>
#include <set>
#include <utility>

#include "common/solver/smoother.h"
#include "server/held_matches.h"
#include "server/keyframe_overlap.h"
#include "server/relative_pose.h"

namespace anchormap {
namespace {

// Points of two scans of one trajectory within about this of each other see one wall: the
// estimate between keyframes some metres apart is good to a few centimetres.
constexpr double kSharedViewDistanceM = 0.1;

// True when a and b will be in one frame once `constraints` are in the graph: each one's group
// (its root once anchored, else itself) and those the constraints between trajectories tie to it.
bool InOneFrameAfter(const Smoother& smoother, const std::vector<EncounterConstraint>& constraints,
                     TrajectoryId a, TrajectoryId b) {
  std::set<TrajectoryFrame> reached{FrameOf(smoother, a)};
  for (bool grew = true; grew;) {
    grew = false;
    for (const EncounterConstraint& c : constraints) {
      const TrajectoryFrame x = FrameOf(smoother, c.a.trajectory);
      const TrajectoryFrame y = FrameOf(smoother, c.b.trajectory);
      if (reached.count(x) != reached.count(y)) {
        reached.insert(x);
        reached.insert(y);
        grew = true;
      }
    }
  }
  return reached.count(FrameOf(smoother, b)) > 0;
}

}  // namespace

void JoinQualifier::Offer(const EncounterCandidate& offered, const GraphView& graph,
                          int64_t now_utime) {
  // Oriented with a in the smaller trajectory id, so that every candidate of a pair compares.
  const EncounterCandidate candidate =
      offered.a.trajectory < offered.b.trajectory ? offered : Reversed(offered);
  const Pair pair{candidate.a.trajectory, candidate.b.trajectory};
  std::deque<Kept>& kept = kept_[pair];
  std::vector<bool> agrees(kept.size(), false);
  // The places that confirm it: agreeing candidates at one place count once.
  std::vector<const Kept*> confirming;
  Kept offered_kept{candidate, 0, Localised(candidate), false};
  if (offered_kept.localised) {
    // Measured once: it also guides global searches (GuidedSubmap).
    const JoinConflict conflict = OwnMapsConflict(candidate, graph);
    offered_kept.verified = MapsAgree(conflict);
    offered_kept.conflict = conflict.pooled_fraction();
    offered_kept.conflict_points = static_cast<int64_t>(conflict.fewer_seen());
  }
  const bool localised = offered_kept.localised;
  const bool verified = offered_kept.verified;
  for (size_t i = 0; localised && i < kept.size(); ++i) {
    if (!kept[i].localised) continue;
    // One place seen twice is no second opinion: the two must be apart in both
    // trajectories (a symmetric spot makes every match there agree).
    const EncounterCandidate& other = kept[i].candidate;
    if (!Independent(kept[i], offered_kept, graph)) continue;
    if (!Consistent(other, candidate, graph, verified && kept[i].verified)) continue;
    agrees[i] = true;
    ++kept[i].support;
    if (std::all_of(confirming.begin(), confirming.end(),
                    [&](const Kept* c) { return Independent(*c, kept[i], graph); })) {
      confirming.push_back(&kept[i]);
    }
  }
  const int consistent = static_cast<int>(confirming.size());
  // The strongest hypothesis this candidate disagrees with.
  int alternative = 0;
  for (size_t i = 0; i < kept.size(); ++i) {
    if (!agrees[i] && kept[i].localised) {
      alternative = std::max(alternative, 1 + kept[i].support);
    }
  }
  // Across the pairs between the same two groups (R1-R3 and R2-R3, R1 and R2 joined): a
  // map-verified candidate of another pair at two places of both groups confirms it too, and
  // any other candidate there is an alternative.
  int alternative_across = alternative;
  if (verified) {
    for (const Pair& sibling : PairsBetweenTheSameGroups(pair, graph)) {
      for (Kept& k : kept_[sibling]) {
        if (!k.localised) continue;
        if (!IndependentAcross(k, offered_kept, graph) ||
            !ConsistentAcross(k.candidate, candidate, graph)) {
          alternative_across = std::max(alternative_across, 1 + k.support);
          continue;
        }
        ++k.support;
        if (std::all_of(confirming.begin(), confirming.end(),
                        [&](const Kept* c) { return IndependentAcross(*c, k, graph); })) {
          confirming.push_back(&k);
        }
      }
    }
  }
  const int confirmed = static_cast<int>(confirming.size());
  if ((consistent >= 1 && 1 + consistent >= options_.alternative_ratio * alternative) ||
      (confirmed > consistent &&
       1 + confirmed >= options_.alternative_ratio * alternative_across)) {
    // Qualified: joins after the hold, unless other evidence joins the pair first.
    qualified_since_.emplace(pair, now_utime);
  }
  offered_kept.support = confirmed;
  kept.push_back(offered_kept);
  ++stats_->kept;
  if (static_cast<int>(kept.size()) > options_.max_kept) {
    kept.pop_front();
    --stats_->kept;
    ++stats_->unconfirmed;
  }
}

bool JoinQualifier::Localised(const EncounterCandidate& candidate) const {
  return anchormap::Localised(candidate.covariance, options_.first_join_max_sigma_m,
                              options_.first_join_max_sigma_rad);
}

bool JoinQualifier::Consistent(const EncounterCandidate& c1, const EncounterCandidate& c2,
                               const GraphView& graph, bool drift) {
  return PairwiseChi2(c1, c2, graph, drift ? options_.verify_drift_per_m : 0.0,
                      drift ? options_.verify_drift_rad_per_m : 0.0,
                      drift ? options_.verify_drift_rad_per_rad : 0.0) <= options_.pcm_chi2;
}

double JoinQualifier::PairwiseChi2(const EncounterCandidate& c1, const EncounterCandidate& c2,
                                   const GraphView& graph, double drift_per_m,
                                   double drift_rad_per_m, double drift_rad_per_rad) {
  const auto driven_to = [this, &graph](PoseKey k) { return driven_->To(graph.table, k); };
  return anchormap::PairwiseChi2(c1, c2, graph, driven_to, drift_per_m, drift_rad_per_m,
                                 drift_rad_per_rad);
}

JoinConflict JoinQualifier::OwnMapsConflict(const EncounterCandidate& candidate,
                                            const GraphView& graph) const {
  const TrajectoryRecord* record_a = graph.table.FindBySolverId(candidate.a.trajectory);
  const TrajectoryRecord* record_b = graph.table.FindBySolverId(candidate.b.trajectory);
  if (record_a == nullptr || record_b == nullptr) return {};
  return MeasureCandidateConflict(*record_a, *record_b, graph.smoother, candidate.a, candidate.b,
                                  candidate.T_a_b, options_.verify_radius_m,
                                  options_.join_check_range_m, options_.free_space);
}

bool JoinQualifier::MapsAgree(const JoinConflict& conflict) const {
  return conflict.fewer_seen() >= static_cast<size_t>(options_.verify_min_points) &&
         conflict.pooled_fraction() <= options_.verify_max_conflict;
}

bool JoinQualifier::ApartAndSeeingOtherWalls(PoseKey k1, PoseKey k2, const GraphView& graph) const {
  return std::abs(k1.index - k2.index) >= 2 * options_.submap_half_width + 1 &&
         Apart(k1, k2, graph) && SharedView(k1, k2, graph) < options_.pcm_max_shared_view;
}

bool JoinQualifier::Apart(PoseKey x, PoseKey y, const GraphView& graph) const {
  const Smoother& smoother = graph.smoother;
  if (!smoother.HasPose(x) || !smoother.HasPose(y)) return false;
  // Straight-line distance in the estimate, not the path: driving back and forth, or
  // turning on the spot, does not make another place.
  if (x.trajectory == y.trajectory) {
    return std::abs(x.index - y.index) >= options_.pcm_min_separation &&
           (smoother.FramePose(x).translation() - smoother.FramePose(y).translation()).norm() >=
               options_.pcm_min_separation_m;
  }
  return (smoother.GlobalPose(x).translation() - smoother.GlobalPose(y).translation()).norm() >=
         options_.pcm_min_separation_m;
}

double JoinQualifier::SharedView(PoseKey x, PoseKey y, const GraphView& graph) const {
  const TrajectoryRecord* record_x = graph.table.FindBySolverId(x.trajectory);
  const TrajectoryRecord* record_y = graph.table.FindBySolverId(y.trajectory);
  if (record_x == nullptr || record_y == nullptr) return 1.0;
  return x.trajectory == y.trajectory
             ? KeyframeOverlap(*record_x, graph.smoother, x.index, y.index, options_.max_range_m,
                               kSharedViewDistanceM)
             : KeyframeOverlap(*record_x, x.index, *record_y, y.index, graph.smoother,
                               options_.max_range_m, kSharedViewDistanceM);
}

bool JoinQualifier::TwoPlaces(const EncounterCandidate& c1, const EncounterCandidate& c2,
                              const GraphView& graph) const {
  // A robot that turns round, or drives on along one corridor, keeps seeing the same walls:
  // what both trajectories see twice is one piece of evidence, however far apart.
  return Apart(c1.a, c2.a, graph) && Apart(c1.b, c2.b, graph) &&
         (SharedView(c1.a, c2.a, graph) < options_.pcm_max_shared_view ||
          SharedView(c1.b, c2.b, graph) < options_.pcm_max_shared_view);
}

bool JoinQualifier::Independent(const Kept& k1, const Kept& k2, const GraphView& graph) const {
  if (TwoPlaces(k1.candidate, k2.candidate, graph)) return true;
  if (!k1.verified || !k2.verified) return false;
  const EncounterCandidate& c1 = k1.candidate;
  const EncounterCandidate& c2 = k2.candidate;
  // One place, two looks: two query scans, each matched against its own stretch of the other
  // trajectory (keyframes that see other walls), so that the two matches share no scan.
  if (c1.query() == c2.query()) return false;
  const PoseKey reference1 = c1.a_is_query ? c1.b : c1.a;
  const PoseKey reference2 = c2.a_is_query ? c2.b : c2.a;
  if (reference1.trajectory != reference2.trajectory) return false;
  // Two looks, not one look twice: a query scan nearly the same as the other (a robot turning
  // a little on the spot) matches every stretch of an aliased corridor alike.
  if (SharedView(c1.query(), c2.query(), graph) >= options_.pcm_max_shared_look) return false;
  return ApartAndSeeingOtherWalls(reference1, reference2, graph);
}

std::vector<JoinQualifier::Pair> JoinQualifier::PairsBetweenTheSameGroups(
    const Pair& pair, const GraphView& graph) const {
  const Smoother& smoother = graph.smoother;
  std::vector<Pair> pairs;
  for (const auto& [other, kept] : kept_) {
    if (other == pair || kept.empty()) continue;
    const bool straight = InOneFrame(smoother, other.first, pair.first) &&
                          InOneFrame(smoother, other.second, pair.second);
    const bool crossed = InOneFrame(smoother, other.first, pair.second) &&
                         InOneFrame(smoother, other.second, pair.first);
    if (straight || crossed) pairs.push_back(other);
  }
  return pairs;
}

namespace {

bool SamePair(const EncounterCandidate& c1, const EncounterCandidate& c2) {
  return c1.a.trajectory == c2.a.trajectory && c1.b.trajectory == c2.b.trajectory;
}

}  // namespace

bool JoinQualifier::IndependentAcross(const Kept& k1, const Kept& k2,
                                      const GraphView& graph) const {
  if (SamePair(k1.candidate, k2.candidate)) return Independent(k1, k2, graph);
  // Only map-verified evidence: a pair of groups offers more ways for aliases to agree.
  if (!k1.localised || !k2.localised || !k1.verified || !k2.verified) return false;
  return TwoPlaces(k1.candidate, OrientedLike(k2.candidate, k1.candidate, graph.smoother), graph);
}

bool JoinQualifier::ConsistentAcross(const EncounterCandidate& c1, const EncounterCandidate& c2,
                                     const GraphView& graph) {
  return Consistent(c1, OrientedLike(c2, c1, graph.smoother), graph, /*drift=*/true);
}

void JoinQualifier::JoinQualified(bool flush, int64_t now_utime, const GraphView& graph,
                                  EncounterSourceOutput* out) {
  for (auto it = qualified_since_.begin(); it != qualified_since_.end();) {
    const Pair pair = it->first;
    const bool joined = InOneFrame(graph.smoother, pair.first, pair.second);
    const bool due =
        1e-6 * static_cast<double>(now_utime - it->second) >= options_.first_join_hold_s;
    if (!joined && !flush && !due) {
      ++it;
      continue;
    }
    it = qualified_since_.erase(it);
    if (joined) continue;  // ResolveKept gates the kept candidates
    // The best supported kept candidate and those consistent with it join the pair.
    std::deque<Kept>& kept = kept_[pair];
    if (kept.empty()) continue;
    size_t best = 0;
    for (size_t i = 1; i < kept.size(); ++i) {
      if (kept[i].localised && (!kept[best].localised || kept[i].support > kept[best].support)) {
        best = i;
      }
    }
    if (!kept[best].localised) continue;
    // The candidates of the pair, then those of the other pairs between the same two groups
    // (IndependentAcross, ConsistentAcross).
    std::vector<const Pair*> pairs{&pair};
    const std::vector<Pair> siblings = PairsBetweenTheSameGroups(pair, graph);
    for (const Pair& sibling : siblings) pairs.push_back(&sibling);
    std::vector<Kept*> members;
    for (const Pair* p : pairs) {
      for (Kept& k : kept_[*p]) members.push_back(&k);
    }
    // A candidate joins with the best one when it agrees with every candidate of the set
    // so far (a clique, as in PCM), not only with the best: two that each agree with the
    // best may still disagree with each other.
    Kept* const best_kept = &kept[best];
    std::vector<Kept*> set{best_kept};
    for (Kept* member : members) {
      if (member == best_kept || !member->localised) continue;
      bool agrees = true;
      for (const Kept* j : set) {
        if (!SamePair(member->candidate, j->candidate)) {
          if (!IndependentAcross(*member, *j, graph) ||
              !ConsistentAcross(member->candidate, j->candidate, graph)) {
            agrees = false;
            break;
          }
          continue;
        }
        const bool same_place = !Independent(*member, *j, graph);
        // Two candidates at one place cannot confirm each other, but one may join the
        // set when another member at another place confirms it.
        if (same_place && j == best_kept) {
          agrees = false;
          break;
        }
        if (!same_place &&
            !Consistent(member->candidate, j->candidate, graph, member->verified && j->verified)) {
          agrees = false;
          break;
        }
      }
      if (agrees) set.push_back(member);
    }
    if (MapsContradict(set, graph)) {
      // Refused for good: its candidates stay kept (gated if the pair joins otherwise) but
      // take no further part in a first join.
      for (Kept* k : set) k->localised = false;
      ++joins_contradicted_;
      continue;
    }
    const std::set<const Kept*> in_set(set.begin(), set.end());
    for (const Pair* p : pairs) {
      std::deque<Kept>& pair_kept = kept_[*p];
      std::deque<Kept> rest;
      for (const Kept& k : pair_kept) {
        if (in_set.count(&k) > 0) {
          Emit(k.candidate, source_name_, out);
          ++stats_->accepted;
          --stats_->kept;
        } else {
          rest.push_back(k);
        }
      }
      pair_kept = std::move(rest);
    }
  }
}

bool JoinQualifier::MapsContradict(const std::vector<Kept*>& set, const GraphView& graph) const {
  const Smoother& smoother = graph.smoother;
  // Each place by its own match: between places 10-20 m apart each robot's estimate drifts
  // by more than the margin (the simulator's LoopWorld, joined truly: 10 % of the points
  // conflicted by the best match's pose alone, all at the far place's walls).
  JoinConflict total;
  for (const Kept* k : set) {
    const EncounterCandidate& c = k->candidate;
    const TrajectoryRecord* record_a = graph.table.FindBySolverId(c.a.trajectory);
    const TrajectoryRecord* record_b = graph.table.FindBySolverId(c.b.trajectory);
    if (record_a == nullptr || record_b == nullptr) return false;
    const JoinConflict conflict = MeasureCandidateConflict(
        *record_a, *record_b, smoother, c.a, c.b, c.T_a_b, options_.join_check_radius_m,
        options_.join_check_range_m, options_.free_space);
    total.a_in_b.seen += conflict.a_in_b.seen;
    total.a_in_b.contradicts += conflict.a_in_b.contradicts;
    total.b_in_a.seen += conflict.b_in_a.seen;
    total.b_in_a.contradicts += conflict.b_in_a.contradicts;
  }
  return total.fraction() > options_.join_max_conflict;
}

std::vector<EncounterCandidate> JoinQualifier::TakeJoined(const GraphView& graph) {
  std::vector<EncounterCandidate> joined;
  for (auto it = kept_.begin(); it != kept_.end();) {
    if (!InOneFrame(graph.smoother, it->first.first, it->first.second)) {
      ++it;
      continue;
    }
    for (const Kept& k : it->second) {
      --stats_->kept;
      joined.push_back(k.candidate);
    }
    it = kept_.erase(it);
  }
  return joined;
}

void JoinQualifier::GiveUpUnlessJoinedBy(const std::vector<EncounterConstraint>& constraints,
                                         const GraphView& graph) {
  for (auto it = kept_.begin(); it != kept_.end();) {
    if (InOneFrameAfter(graph.smoother, constraints, it->first.first, it->first.second)) {
      ++it;
      continue;
    }
    GiveUpHeld(&it->second, stats_);
    it = kept_.erase(it);
  }
}

const EncounterCandidate* JoinQualifier::BestHypothesis(
    TrajectoryId query, const std::function<bool(TrajectoryId)>& accept, int min_points) const {
  const Kept* best = nullptr;
  for (const auto& [pair, kept] : kept_) {
    const bool first = pair.first == query;
    if (!first && pair.second != query) continue;
    if (!accept(first ? pair.second : pair.first)) continue;
    for (const Kept& k : kept) {
      if (!k.localised || k.conflict_points < min_points ||
          k.conflict > options_.verify_max_conflict) {
        continue;
      }
      if (best == nullptr || k.conflict < best->conflict) best = &k;
    }
  }
  return best != nullptr ? &best->candidate : nullptr;
}

void JoinQualifier::ExportState(ScanEncounterState* s) const {
  for (const auto& [pair, kept] : kept_) {
    auto& out = s->kept[pair];
    for (const Kept& k : kept)
      out.push_back({ToState(k.candidate), k.support, k.localised, k.verified, k.conflict,
                     k.conflict_points});
  }
  s->qualified_since = qualified_since_;
}

void JoinQualifier::ImportState(const ScanEncounterState& s) {
  kept_.clear();
  for (const auto& [pair, kept] : s.kept) {
    std::deque<Kept>& out = kept_[pair];
    for (const ScanEncounterState::Kept& k : kept) {
      out.push_back({FromState(k.candidate), k.support, k.localised, k.verified, k.conflict,
                     k.conflict_points});
    }
  }
  qualified_since_ = s.qualified_since;
}

}  // namespace anchormap
