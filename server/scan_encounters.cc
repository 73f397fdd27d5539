#include "server/scan_encounters.h"

#include <algorithm>
#include <cmath>
#include <future>
#include <limits>
#include <memory>
#include <set>

#include <Eigen/Eigenvalues>

#include "common/scan_matching/point_cloud.h"
#include "server/held_matches.h"
#include "server/join_free_space.h"
#include "server/keyframe_overlap.h"
#include "server/keyframe_submap.h"
#include "server/relative_pose.h"

namespace anchormap {

namespace {}  // namespace

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
         " near_over_budget " + std::to_string(near_.budget().skipped()) + " look_backs " +
         std::to_string(look_backs_) + " " + submaps_.references().stats().Summary(name());
}

void ScanEncounters::Poll(int64_t now_utime, const GraphView& graph, EncounterSourceOutput* out) {
  now_utime_ = std::max(now_utime_, now_utime);
  global_.queue().Advance(now_utime_);
  near_.Advance(now_utime_);
  Examine(graph, out);
  qualifier_.JoinQualified(/*flush=*/false, now_utime_, graph, out);
}

void ScanEncounters::Flush(const GraphView& graph, EncounterSourceOutput* out) {
  Examine(graph, out);
  if (graph.covariances != nullptr) UseMatches(/*all=*/true, graph, out);
  qualifier_.JoinQualified(/*flush=*/true, now_utime_, graph, out);
  qualifier_.GiveUpUnlessJoinedBy(out->constraints, graph);
  near_.GiveUpHeld();
}

void ScanEncounters::Examine(const GraphView& graph, EncounterSourceOutput* out) {
  if (graph.covariances == nullptr) return;
  ResolveKept(graph, out);
  submaps_.Build(graph);
  const TrajectoryFrames frames =
      FramesOf(graph.table, graph.smoother);  // neither step below changes a frame
  near_.CatchUpJoined(frames, waiting_, graph);
  LookBackOnGroupChange(frames, graph);
  std::deque<PoseKey> still_waiting;
  std::vector<BudgetRequest> ready;
  for (const PoseKey key : waiting_) {
    if (!graph.covariances->HasCovariance(key)) {
      still_waiting.push_back(key);
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

void ScanEncounters::LookBackOnGroupChange(const TrajectoryFrames& frames, const GraphView& graph) {
  const Smoother& smoother = graph.smoother;
  const std::deque<TrajectoryRecord>& records = graph.table.records();
  if (frames == looked_back_frames_) return;
  const std::map<TrajectoryId, TrajectoryFrame> before(looked_back_frames_.begin(),
                                                       looked_back_frames_.end());
  looked_back_frames_ = frames;
  if (before.empty() || options_.look_back_max_per_change < 1) return;
  // Two trajectories newly in one frame (a trajectory new since counts as alone before).
  const auto newly_joined = [&](TrajectoryId x, TrajectoryId y) {
    const auto bx = before.find(x);
    const auto by = before.find(y);
    return x != y && InOneFrame(smoother, x, y) &&
           (bx == before.end() || by == before.end() || bx->second != by->second);
  };
  // Per (query, other) pair its looks, nearest first; the pairs take turns up to the cap (a
  // pair with many keyframes near does not crowd out another's).
  std::vector<std::vector<LookBack>> per_pair;
  for (const TrajectoryRecord& query : records) {
    for (const TrajectoryRecord& other : records) {
      const TrajectoryId y = other.solver_id;
      if (y == query.solver_id || InOneFrame(smoother, query.solver_id, y)) continue;
      // The query's best hypothesis against a trajectory that came into y's frame.
      const EncounterCandidate* hypothesis = qualifier_.BestHypothesis(
          query.solver_id, [&](TrajectoryId x) { return newly_joined(x, y); });
      if (hypothesis == nullptr) continue;
      std::vector<LookBack> pair_looks = LookBacks(*hypothesis, y, graph);
      if (pair_looks.empty()) continue;
      std::sort(pair_looks.begin(), pair_looks.end(), [](const LookBack& l1, const LookBack& l2) {
        return l1.distance != l2.distance ? l1.distance < l2.distance : l1.key.index < l2.key.index;
      });
      per_pair.push_back(std::move(pair_looks));
    }
  }
  std::vector<LookBack> looks;
  const size_t most = static_cast<size_t>(options_.look_back_max_per_change);
  for (size_t turn = 0; looks.size() < most; ++turn) {
    bool any = false;
    for (const std::vector<LookBack>& pair_looks : per_pair) {
      if (turn >= pair_looks.size() || looks.size() >= most) continue;
      looks.push_back(pair_looks[turn]);
      any = true;
    }
    if (!any) break;
  }
  GlobalSearchOptions search;
  search.match = options_.match;
  search.match.min_score = options_.global_min_score;
  search.match.covariance_min_overlap = options_.global_min_overlap;  // UseMatches' bar
  for (const LookBack& look : looks) {
    const Submap& submap = submaps_.Of(look.other)[look.submap];
    const TrajectoryRecord* record = graph.table.FindBySolverId(look.key.trajectory);
    std::shared_ptr<const ScanReference> reference = submaps_.Reference(submap, graph);
    if (record == nullptr || !reference) continue;
    auto query = std::make_shared<const PointCloud>(
        KeyframePoints(*record, look.key.index, options_.max_range_m));
    if (query->empty()) continue;
    // A global search of the submap, as a guided one: the hypothesis chose the submap, not the
    // pose in it, so a match that agrees with the hypothesis is evidence of its own. Not paid
    // from the global searches' tokens (bounded by the cap per group change instead): charged,
    // the searches after it moved by the cap's tokens and FR079 split in three
    // simultaneously joined R3 48 s later, with more searches.
    matches_.Submit(
        look.key, submap.center, /*global=*/true, /*wide=*/false,
        record->utimes[static_cast<size_t>(look.key.index)],
        [reference, query, search] { return GlobalSearch(*reference, *query, search); },
        now_utime_);
    ++look_backs_;
  }
}

std::vector<ScanEncounters::LookBack> ScanEncounters::LookBacks(
    const EncounterCandidate& hypothesis, TrajectoryId other, const GraphView& graph) {
  const Smoother& smoother = graph.smoother;
  const std::vector<Submap>& submaps = submaps_.Of(other);
  // Oriented with a in the group, b the querying trajectory's keyframe.
  const EncounterCandidate c =
      InOneFrame(smoother, hypothesis.a.trajectory, other) ? hypothesis : Reversed(hypothesis);
  const TrajectoryRecord* record = graph.table.FindBySolverId(c.b.trajectory);
  if (record == nullptr || submaps.empty() || !smoother.HasPose(c.a) || !smoother.HasPose(c.b)) {
    return {};
  }
  std::set<int32_t> waiting;
  for (const PoseKey key : waiting_) {
    if (key.trajectory == c.b.trajectory) waiting.insert(key.index);
  }
  // The query trajectory's frame placed in the group's frame by the hypothesis.
  const Pose2 T_global_frame =
      Compose(Compose(smoother.GlobalPose(c.a), c.T_a_b), smoother.FramePose(c.b).Inverse());
  const double reach = options_.near_distance_m + options_.near_wide_max_window_m;
  const double driven_hypothesis = DrivenTo(c.b, graph);
  std::vector<LookBack> looks;
  for (int32_t k = 0; k < record->num_keyframes(); ++k) {
    const PoseKey key{c.b.trajectory, k};
    if (key == c.b || waiting.count(k) > 0 || !graph.covariances->HasCovariance(key) ||
        record->scans[static_cast<size_t>(k)].ranges.empty()) {
      continue;
    }
    const Pose2 T_global_key = Compose(T_global_frame, smoother.FramePose(key));
    std::optional<LookBack> nearest;
    for (size_t i = 0; i < submaps.size(); ++i) {
      const Submap& submap = submaps[i];
      if (submap.drawing.num_points == 0 || !smoother.HasPose(submap.center)) continue;
      const double d =
          (smoother.GlobalPose(submap.center).translation() - T_global_key.translation()).norm();
      if (d < reach && (!nearest || d < nearest->distance)) {
        nearest = LookBack{d, key, other, i};
      }
    }
    if (!nearest) continue;
    // The drift of the query's path from the hypothesis's keyframe and of the group's from its
    // keyframe to the submap, through the ties (the near search's window drift).
    const Eigen::Matrix3d covariance =
        c.covariance + NearDriftOf(std::abs(DrivenTo(key, graph) - driven_hypothesis), options_) +
        NearWindowDrift(c.a, submaps[nearest->submap].center, graph);
    const double three_sigma = std::min(3.0 * LargestSigma(covariance.topLeftCorner<2, 2>()),
                                        options_.near_wide_max_window_m);
    if (nearest->distance <= options_.near_distance_m + three_sigma) looks.push_back(*nearest);
  }
  return looks;
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
  if (WithinGate(candidate, graph, widened, Eigen::Matrix3d::Zero())) return true;
  ++stats_.gate_rejected;
  return false;
}

bool ScanEncounters::WithinGate(const EncounterCandidate& candidate, const GraphView& graph,
                                bool widened, const Eigen::Matrix3d& drift) const {
  return anchormap::WithinGate(candidate, graph, widened, drift, options_);
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
