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
         std::to_string(global_queue_.searches()) + " global_replaced " +
         std::to_string(global_queue_.dropped()) + " near_saturated " +
         std::to_string(near_.saturated()) + " near_capped " + std::to_string(near_.capped()) +
         " near_over_budget " + std::to_string(near_.budget().skipped()) + " look_backs " +
         std::to_string(look_backs_) + " " + submaps_.references().stats().Summary(name());
}

void ScanEncounters::Poll(int64_t now_utime, const GraphView& graph, EncounterSourceOutput* out) {
  now_utime_ = std::max(now_utime_, now_utime);
  global_queue_.Advance(now_utime_);
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
  ServeGlobalQueue(graph);  // tokens accrued since the last keyframe
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
    global_queue_.Enqueue(key);
    ServeGlobalQueue(graph);
  }
  return searches;
}

void ScanEncounters::ServeGlobalQueue(const GraphView& graph) {
  const int most_per_target = std::max(0, options_.max_global_per_keyframe);
  for (std::optional<PoseKey> key = global_queue_.Next(); key; key = global_queue_.Next()) {
    const std::vector<GlobalTarget> targets = GlobalTargets(*key, graph);
    int cost = 0;
    for (const GlobalTarget& target : targets) {
      cost += static_cast<int>(
          std::min(submaps_.Of(target.other).size(), static_cast<size_t>(most_per_target)));
    }
    // Waits for tokens (every keyframe's cost is at most the burst, so it will be served
    // unless a newer keyframe of its trajectory replaces it).
    if (cost > 0 && !global_queue_.CanAfford(cost)) return;
    int spent = 0;
    for (const GlobalTarget& target : targets) spent += SearchGlobally(*key, target, graph);
    global_queue_.Served(*key, spent);
  }
}

std::vector<ScanEncounters::GlobalTarget> ScanEncounters::GlobalTargets(
    PoseKey key, const GraphView& graph) const {
  // Per other group, the trajectory whose pair with key's was searched least (then the
  // smaller id); then the groups whose best pair was searched least.
  std::map<TrajectoryFrame, std::pair<int64_t, TrajectoryId>> best;
  for (const TrajectoryRecord& other : graph.table.records()) {
    const TrajectoryId id = other.solver_id;
    if (id == key.trajectory || InOneFrame(graph.smoother, key.trajectory, id)) continue;
    const std::vector<Submap>* submaps = submaps_.Find(id);
    if (submaps == nullptr || submaps->empty()) continue;
    const std::pair<int64_t, TrajectoryId> rank{global_queue_.PairSearches(key.trajectory, id), id};
    const auto [it, inserted] = best.emplace(FrameOf(graph.smoother, id), rank);
    if (!inserted && rank < it->second) it->second = rank;
  }
  // A group's trajectory is, instead, the one a kept hypothesis guides the search to (the
  // nearest guided submap, then the smaller id), when there is one: the trajectory searched
  // least is far from the place the hypothesis puts the keyframe. The guided submaps are
  // those SearchGlobally takes (computed once: they do not change in between).
  std::map<TrajectoryFrame, std::pair<double, TrajectoryId>> guided;
  std::map<TrajectoryId, std::vector<size_t>> guided_submaps;
  for (const TrajectoryRecord& other : graph.table.records()) {
    const TrajectoryId id = other.solver_id;
    if (id == key.trajectory || InOneFrame(graph.smoother, key.trajectory, id)) continue;
    double distance_m = 0.0;
    std::vector<size_t> submaps =
        GuidedSubmaps(key, id, graph, std::max<size_t>(1, GlobalTries(id)), &distance_m);
    if (submaps.empty()) continue;
    guided_submaps.emplace(id, std::move(submaps));
    const std::pair<double, TrajectoryId> rank{distance_m, id};
    const auto [it, inserted] = guided.emplace(FrameOf(graph.smoother, id), rank);
    if (!inserted && rank < it->second) it->second = rank;
  }
  std::vector<std::pair<int64_t, TrajectoryId>> ranked;
  for (const auto& [group, rank] : best) {
    const auto it = guided.find(group);
    ranked.push_back(it == guided.end() ? rank : std::make_pair(rank.first, it->second.second));
  }
  std::sort(ranked.begin(), ranked.end());
  const size_t take = std::min(
      ranked.size(), static_cast<size_t>(std::max(0, options_.max_global_groups_per_keyframe)));
  std::vector<GlobalTarget> targets;
  for (size_t i = 0; i < take; ++i) {
    const auto it = guided_submaps.find(ranked[i].second);
    targets.push_back(
        {ranked[i].second, it != guided_submaps.end() ? it->second : std::vector<size_t>{}});
  }
  // Searched in id order, as before the budget (the order the matches are used in).
  std::sort(targets.begin(), targets.end(),
            [](const GlobalTarget& x, const GlobalTarget& y) { return x.other < y.other; });
  return targets;
}

size_t ScanEncounters::GlobalTries(TrajectoryId other) const {
  const std::vector<Submap>* submaps = submaps_.Find(other);
  if (submaps == nullptr) return 0;
  return std::min(submaps->size(),
                  static_cast<size_t>(std::max(0, options_.max_global_per_keyframe)));
}

int ScanEncounters::SearchGlobally(PoseKey key, const GlobalTarget& target,
                                   const GraphView& graph) {
  const TrajectoryId other = target.other;
  std::vector<Submap>& submaps = submaps_.Of(other);
  if (submaps.empty()) return 0;
  const TrajectoryRecord* record = graph.table.FindBySolverId(key.trajectory);
  if (record == nullptr || key.index >= record->num_keyframes()) return 0;
  auto query =
      std::make_shared<const PointCloud>(KeyframePoints(*record, key.index, options_.max_range_m));
  if (query->empty()) return 0;
  GlobalSearchOptions search;
  search.match = options_.match;
  search.match.min_score = options_.global_min_score;
  search.match.covariance_min_overlap = options_.global_min_overlap;  // UseMatches' bar
  size_t& cursor = global_cursor_[{key.trajectory, other}];
  const size_t tries = GlobalTries(other);
  // The submaps nearest where the best kept hypothesis, if any, puts the keyframe, instead of
  // the next ones in turn: the same number of searches.
  std::vector<size_t> guided = target.guided;
  if (guided.size() > tries) guided.resize(tries);
  int submitted = 0;
  for (size_t t = 0; t < tries; ++t) {
    size_t index = 0;
    if (t < guided.size()) {
      index = guided[t];
    } else {
      // The cursor counts the searches: modulo a list that grows it steps back by one for
      // every round done, so a trajectory still driving is searched along one stretch for a
      // while (ACES split in three simultaneously: R3 searched R1[85], [75] ... [25] while it
      // passed R1[115]). Taking the submaps round by round joined R3 there (0.0393, with the
      // end-of-input join finished), but lost R1-R2's join on two of three rotated copies of
      // that log and delayed FR079 split in three's joins (more global searches): kept.
      index = cursor++ % submaps.size();
      // Not a guided submap a second time: the next one in turn instead.
      for (size_t skipped = 0; skipped + 1 < submaps.size() &&
                               std::find(guided.begin(), guided.end(), index) != guided.end();
           ++skipped) {
        index = cursor++ % submaps.size();
      }
    }
    Submap& submap = submaps[index];
    std::shared_ptr<const ScanReference> reference = submaps_.Reference(submap, graph);
    if (!reference) continue;
    matches_.Submit(key, submap.center, /*global=*/true, /*wide=*/false,
                    record->utimes[static_cast<size_t>(key.index)], [reference, query, search] {
                      return GlobalSearch(*reference, *query, search);
                    });
    ++submitted;
  }
  global_queue_.CountPair(key.trajectory, other, submitted);
  return submitted;
}

std::vector<size_t> ScanEncounters::GuidedByHypothesis(PoseKey key,
                                                       const EncounterCandidate& hypothesis,
                                                       const std::vector<Submap>& submaps,
                                                       const GraphView& graph, size_t most,
                                                       double* nearest_m) const {
  const Smoother& smoother = graph.smoother;
  // Oriented with b in key's trajectory; key placed in the group's frame through it.
  const EncounterCandidate c =
      hypothesis.a.trajectory == key.trajectory ? Reversed(hypothesis) : hypothesis;
  if (!smoother.HasPose(c.a) || !smoother.HasPose(c.b) || !smoother.HasPose(key)) return {};
  const Pose2 T_global_key =
      Compose(Compose(smoother.GlobalPose(c.a), c.T_a_b),
              Compose(smoother.FramePose(c.b).Inverse(), smoother.FramePose(key)));
  std::vector<std::pair<double, size_t>> near;
  for (size_t i = 0; i < submaps.size(); ++i) {
    const Submap& submap = submaps[i];
    if (submap.drawing.num_points == 0 || !smoother.HasPose(submap.center)) continue;
    const double d =
        (smoother.GlobalPose(submap.center).translation() - T_global_key.translation()).norm();
    if (d < options_.guide_max_distance_m) near.emplace_back(d, i);
  }
  std::sort(near.begin(), near.end());
  if (near.size() > most) near.resize(most);
  if (!near.empty() && nearest_m != nullptr) *nearest_m = near.front().first;
  std::vector<size_t> nearest;
  for (const auto& [d, i] : near) nearest.push_back(i);
  return nearest;
}

std::vector<size_t> ScanEncounters::GuidedSubmaps(PoseKey key, TrajectoryId other,
                                                  const GraphView& graph, size_t most,
                                                  double* nearest_m) const {
  const Smoother& smoother = graph.smoother;
  const std::vector<Submap>* submaps = submaps_.Find(other);
  if (options_.guide_max_distance_m <= 0 || submaps == nullptr || most == 0) return {};
  // Only against a group of two trajectories or more: a single one is searched in turn, as
  // it always was (its first join needs two places of it, which the turn reaches).
  const std::deque<TrajectoryRecord>& records = graph.table.records();
  if (std::none_of(records.begin(), records.end(), [&](const TrajectoryRecord& r) {
        return r.solver_id != other && InOneFrame(smoother, r.solver_id, other);
      })) {
    return {};
  }
  // The kept candidate of key's trajectory against the target's group whose own maps agree
  // best.
  const EncounterCandidate* best = qualifier_.BestHypothesis(
      key.trajectory, [&](TrajectoryId id) { return InOneFrame(smoother, id, other); });
  if (best == nullptr) return {};
  return GuidedByHypothesis(key, *best, *submaps, graph, most, nearest_m);
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
