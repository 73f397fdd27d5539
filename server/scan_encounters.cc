#include "server/scan_encounters.h"

#include <algorithm>
#include <optional>
#include <utility>
#include <vector>

#include "common/solver/smoother.h"
#include "server/relative_pose.h"
#include "server/trajectory_table.h"

namespace anchormap {

void ScanEncounters::OnKeyframeAdded(PoseKey key, const GraphView& /*graph*/,
                                     EncounterSourceOutput* /*out*/) {
  waiting_.push_back(key);
  while (static_cast<int>(waiting_.size()) > options_.max_waiting) waiting_.pop_front();
}

std::string ScanEncounters::StatsLine() const {
  return stats_.Summary(name()) + " joins_contradicted " +
         std::to_string(qualifier_.joins_contradicted()) + " global_searches " +
         std::to_string(global_.queue().searches()) + " global_replaced " +
         std::to_string(global_.queue().dropped()) + " near_saturated " +
         std::to_string(near_.saturated()) + " near_capped " + std::to_string(near_.capped()) +
         " near_over_budget " + std::to_string(near_.budget().skipped()) + " near_folded " +
         std::to_string(near_folded_) + " look_backs " + std::to_string(look_back_.look_backs()) +
         " " + submaps_.references().stats().Summary(name());
}

void ScanEncounters::Poll(int64_t now_utime, const GraphView& graph, EncounterSourceOutput* out) {
  now_utime_ = std::max(now_utime_, now_utime);
  global_.queue().Advance(now_utime_);
  near_.Advance(now_utime_);
  Examine(graph, out);
  qualifier_.JoinQualified(/*flush=*/false, now_utime_, graph, out);
}

void ScanEncounters::Flush(const GraphView& graph, EncounterSourceOutput* out) {
  Examine(graph, out, /*at_end=*/true);
  if (graph.covariances != nullptr) UseMatches(/*all=*/true, graph, out);
  qualifier_.JoinQualified(/*flush=*/true, now_utime_, graph, out);
  qualifier_.GiveUpUnlessJoinedBy(out->constraints, graph);
  near_.GiveUpHeld();
}

bool ScanEncounters::FoldedTooRecently(PoseKey key, const GraphView& graph) const {
  if (!(options_.folded_wait_s > 0)) return false;
  const TrajectoryRecord* record = graph.table.FindBySolverId(key.trajectory);
  if (record == nullptr || key.index < 0 || key.index >= record->num_keyframes()) return false;
  const int64_t key_utime = record->utimes[static_cast<size_t>(key.index)];
  return now_utime_ - key_utime < static_cast<int64_t>(1e6 * options_.folded_wait_s);
}

void ScanEncounters::Examine(const GraphView& graph, EncounterSourceOutput* out, bool at_end) {
  if (graph.covariances == nullptr) return;
  ResolveKept(graph, out);
  submaps_.Build(graph);
  // Neither step below changes a frame.
  const TrajectoryFrames frames = FramesOf(graph.table, graph.smoother);
  near_.CatchUpJoined(frames, waiting_, graph);
  look_back_.LookBackOnGroupChange(frames, waiting_, now_utime_, graph);
  std::deque<PoseKey> still_waiting;
  std::vector<BudgetRequest> ready;
  std::vector<PoseKey> folded;
  for (const PoseKey key : waiting_) {
    if (!graph.covariances->HasCovariance(key)) {
      still_waiting.push_back(key);
      continue;
    }
    // A keyframe folded onto a node (the reduced graph) is tied where it is by the fold's
    // match: the node's own near searches and the folds of the group's other trajectories
    // onto it tie the place. Only its global search (a group the fold cannot join) is left.
    if (graph.smoother.IsFolded(key)) {
      if (!at_end && FoldedTooRecently(key, graph)) {
        still_waiting.push_back(key);
        continue;
      }
      folded.push_back(key);
      continue;
    }
    ready.push_back({key, near_.budget().bounded() ? DrivenTo(key, graph) : 0.0});
  }
  waiting_ = std::move(still_waiting);
  const double most_per_keyframe = options_.near_max_partners > 0
                                       ? options_.near_max_partners
                                       : static_cast<double>(graph.table.records().size());
  const std::vector<PoseKey> skipped =
      near_.budget().Serve(ready, most_per_keyframe, [&](PoseKey key) {
        const int searches = ExamineKeyframe(key, graph, /*near=*/true);
        UseMatches(/*all=*/false, graph, out);
        return static_cast<double>(searches);
      });
  // Over the near budget: their global searches still wait for theirs.
  for (const PoseKey key : skipped) ExamineKeyframe(key, graph, /*near=*/false);
  for (const PoseKey key : folded) ExamineKeyframe(key, graph, /*near=*/false);
  near_folded_ += static_cast<int64_t>(folded.size());
  global_.ServeGlobalQueue(graph);  // tokens accrued since the last keyframe
  UseMatches(/*all=*/false, graph, out);
}

int ScanEncounters::ExamineKeyframe(PoseKey key, const GraphView& graph, bool near_too) {
  const TrajectoryRecord* record = graph.table.FindBySolverId(key.trajectory);
  if (record == nullptr || key.index >= record->num_keyframes()) return 0;
  if (record->scans[static_cast<size_t>(key.index)].ranges.empty()) return 0;
  bool unjoined = false;
  for (const TrajectoryRecord& other : graph.table.records()) {
    if (other.solver_id != key.trajectory &&
        !InOneFrame(graph.smoother, key.trajectory, other.solver_id)) {
      unjoined = true;
      break;
    }
  }
  int searches = 0;
  if (near_too) {
    for (const NearSearch::NearTarget& target : near_.Targets(key, graph)) {
      searches += near_.SearchNear(key, target, graph) ? 1 : 0;
    }
  }
  if (unjoined && key.index % options_.global_every == 0) {
    global_.queue().Enqueue(key);
    global_.ServeGlobalQueue(graph);
  }
  return searches;
}

void ScanEncounters::UseMatches(bool all, const GraphView& graph, EncounterSourceOutput* out) {
  // A keyframe that joined two trajectories by one global match is not searched further
  // against that trajectory (its other submaps' matches are dropped unused).
  std::optional<std::pair<PoseKey, TrajectoryId>> joined;
  while (std::optional<EncounterMatches::Pending> due = matches_.NextDue(all, now_utime_)) {
    const EncounterMatches::Pending pending = std::move(*due);
    const std::optional<MatchResult> match = pending.result.get();
    if (pending.global && joined && joined->first == pending.key &&
        joined->second == pending.center.trajectory) {
      continue;
    }
    ++stats_.candidates;
    if (!match) {
      ++stats_.no_match;
      continue;
    }
    const double min_score = pending.global ? 0.0 : options_.near_min_score;
    const double min_overlap =
        pending.global ? options_.global_min_overlap : options_.near_min_overlap;
    if (match->score < min_score || match->overlap < min_overlap) {
      ++stats_.weak_match;
      continue;
    }
    EncounterCandidate candidate;
    candidate.a = pending.center;
    candidate.b = pending.key;
    candidate.T_a_b = match->pose;
    candidate.covariance =
        WithCovarianceFloor(match->covariance, options_.floor_sigma_m, options_.floor_sigma_rad);
    candidate.utime = pending.key_utime;
    if (pending.global) {
      OfferCandidate(candidate, graph, out);
      // Joined now (or waiting for the update that joins them): no further search.
      if (!out->constraints.empty() && out->constraints.back().b == pending.key) {
        joined = std::make_pair(pending.key, pending.center.trajectory);
      }
    } else {
      near_.OfferNearMatch(candidate, pending.wide, graph, out);
    }
  }
}

double ScanEncounters::DrivenTo(PoseKey key, const GraphView& graph) {
  return driven_.To(graph.table, key);
}

void ScanEncounters::OfferNearMatch(const EncounterCandidate& candidate, bool wide,
                                    const GraphView& graph, EncounterSourceOutput* out) {
  near_.OfferNearMatch(candidate, wide, graph, out);
}

Eigen::Matrix3d ScanEncounters::NearDrift(PoseKey a, PoseKey b, const GraphView& graph) {
  return near_.NearDrift(a, b, graph);
}

Eigen::Matrix3d ScanEncounters::NearWindowDrift(PoseKey a, PoseKey b, const GraphView& graph) {
  return near_.NearWindowDrift(a, b, graph);
}

void ScanEncounters::OfferCandidate(const EncounterCandidate& offered, const GraphView& graph,
                                    EncounterSourceOutput* out) {
  if (graph.covariances == nullptr || offered.a.trajectory == offered.b.trajectory) return;
  if (InOneFrame(graph.smoother, offered.a.trajectory, offered.b.trajectory)) {
    GateAndEmit(offered, graph, out);
    return;
  }
  qualifier_.Offer(offered, graph, now_utime_);
}

void ScanEncounters::ResolveKept(const GraphView& graph, EncounterSourceOutput* out) {
  for (const EncounterCandidate& candidate : qualifier_.TakeJoined(graph)) {
    GateAndEmit(candidate, graph, out);
  }
}

bool ScanEncounters::PassesGate(const EncounterCandidate& candidate, const GraphView& graph,
                                bool widened) {
  if (WithinGate(candidate, graph, widened, Eigen::Matrix3d::Zero(), options_)) return true;
  ++stats_.gate_rejected;
  return false;
}

bool ScanEncounters::GateAndEmit(const EncounterCandidate& candidate, const GraphView& graph,
                                 EncounterSourceOutput* out) {
  if (!PassesGate(candidate, graph, /*widened=*/false)) return false;
  ++stats_.accepted;
  Emit(candidate, out);
  return true;
}

void ScanEncounters::Emit(const EncounterCandidate& candidate, EncounterSourceOutput* out) {
  anchormap::Emit(candidate, name(), out);
}

}  // namespace anchormap
