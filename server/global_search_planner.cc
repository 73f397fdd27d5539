#include "server/global_search_planner.h"

#include <algorithm>
#include <map>
#include <memory>
#include <utility>

#include "common/scan_matching/global_search.h"
#include "common/scan_matching/point_cloud.h"
#include "common/solver/smoother.h"
#include "server/relative_pose.h"

namespace anchormap {

void GlobalSearchPlanner::ServeGlobalQueue(const GraphView& graph) {
  const int most_per_target = std::max(0, options_.max_global_per_keyframe);
  for (std::optional<PoseKey> key = global_queue_.Next(); key; key = global_queue_.Next()) {
    // Every target costs at least one search: without a token for one, a head with any target
    // waits whatever its targets are, and ranking them (GlobalTargets, ~1 % of a 100 x 180
    // replay, asked at every examined keyframe while the head waited) is not needed to know.
    if (most_per_target >= 1 && !global_queue_.CanAfford(1) && HasGlobalTarget(*key, graph)) {
      return;
    }
    const std::vector<GlobalTarget> targets = GlobalTargets(*key, graph);
    int cost = 0;
    for (const GlobalTarget& target : targets) {
      cost += static_cast<int>(
          std::min(submaps_->Of(target.other).size(), static_cast<size_t>(most_per_target)));
    }
    // Waits for tokens (every keyframe's cost is at most the burst, so it will be served
    // unless a newer keyframe of its trajectory replaces it).
    if (cost > 0 && !global_queue_.CanAfford(cost)) return;
    int spent = 0;
    for (const GlobalTarget& target : targets) spent += SearchGlobally(*key, target, graph);
    global_queue_.Served(*key, spent);
  }
}

bool GlobalSearchPlanner::IsGlobalTarget(PoseKey key, TrajectoryId id,
                                         const GraphView& graph) const {
  if (id == key.trajectory || InOneFrame(graph.smoother, key.trajectory, id)) return false;
  const std::vector<Submap>* submaps = submaps_->Find(id);
  return submaps != nullptr && !submaps->empty();
}

bool GlobalSearchPlanner::HasGlobalTarget(PoseKey key, const GraphView& graph) const {
  if (options_.max_global_groups_per_keyframe < 1) return false;
  // GlobalTargets' first pass, stopped at the first trajectory it would rank.
  const auto& records = graph.table.records();
  return std::any_of(records.begin(), records.end(), [&](const TrajectoryRecord& other) {
    return IsGlobalTarget(key, other.solver_id, graph);
  });
}

std::vector<GlobalSearchPlanner::GlobalTarget> GlobalSearchPlanner::GlobalTargets(
    PoseKey key, const GraphView& graph) const {
  // Per other group, the trajectory whose pair with key's was searched least (then the
  // smaller id); then the groups whose best pair was searched least.
  std::map<TrajectoryFrame, std::pair<int64_t, TrajectoryId>> best;
  for (const TrajectoryRecord& other : graph.table.records()) {
    const TrajectoryId id = other.solver_id;
    if (!IsGlobalTarget(key, id, graph)) continue;
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
  // The table's trajectories per anchored group, counted once here rather than by a pass over
  // the table per trajectory (InOneFrame with each of 100 others: ~1 % of a 100 x 180 replay).
  std::map<TrajectoryId, int> group_sizes;
  for (const auto& [id, frame] : FramesOf(graph.table, graph.smoother)) {
    if (frame.first) ++group_sizes[frame.second];
  }
  for (const TrajectoryRecord& other : graph.table.records()) {
    const TrajectoryId id = other.solver_id;
    if (id == key.trajectory || InOneFrame(graph.smoother, key.trajectory, id)) continue;
    const TrajectoryFrame frame = FrameOf(graph.smoother, id);
    const bool grouped = frame.first && group_sizes[frame.second] >= 2;
    double distance_m = 0.0;
    std::vector<size_t> submaps =
        GuidedSubmaps(key, id, grouped, graph, std::max<size_t>(1, GlobalTries(id)), &distance_m);
    if (submaps.empty()) continue;
    guided_submaps.emplace(id, std::move(submaps));
    const std::pair<double, TrajectoryId> rank{distance_m, id};
    const auto [it, inserted] = guided.emplace(frame, rank);
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

size_t GlobalSearchPlanner::GlobalTries(TrajectoryId other) const {
  const std::vector<Submap>* submaps = submaps_->Find(other);
  if (submaps == nullptr) return 0;
  return std::min(submaps->size(),
                  static_cast<size_t>(std::max(0, options_.max_global_per_keyframe)));
}

int GlobalSearchPlanner::SearchGlobally(PoseKey key, const GlobalTarget& target,
                                        const GraphView& graph) {
  const TrajectoryId other = target.other;
  std::vector<Submap>& submaps = submaps_->Of(other);
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
    std::shared_ptr<const ScanReference> reference = submaps_->Reference(submap, graph);
    if (!reference) continue;
    matches_->Submit(key, submap.center, /*global=*/true, /*wide=*/false,
                     record->utimes[static_cast<size_t>(key.index)], [reference, query, search] {
                       return GlobalSearch(*reference, *query, search);
                     });
    ++submitted;
  }
  global_queue_.CountPair(key.trajectory, other, submitted);
  return submitted;
}

std::vector<size_t> GlobalSearchPlanner::GuidedByHypothesis(PoseKey key,
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

std::vector<size_t> GlobalSearchPlanner::GuidedSubmaps(PoseKey key, TrajectoryId other,
                                                       bool grouped, const GraphView& graph,
                                                       size_t most, double* nearest_m) const {
  const Smoother& smoother = graph.smoother;
  const std::vector<Submap>* submaps = submaps_->Find(other);
  if (options_.guide_max_distance_m <= 0 || submaps == nullptr || most == 0) return {};
  // Only against a group of two trajectories or more: a single one is searched in turn, as
  // it always was (its first join needs two places of it, which the turn reaches).
  if (!grouped) return {};
  // The kept candidate of key's trajectory against the target's group whose own maps agree
  // best.
  const EncounterCandidate* best = qualifier_->BestHypothesis(
      key.trajectory, [&](TrajectoryId id) { return InOneFrame(smoother, id, other); },
      options_.guide_min_points);
  if (best == nullptr) return {};
  return GuidedByHypothesis(key, *best, *submaps, graph, most, nearest_m);
}

void GlobalSearchPlanner::ExportState(ScanEncounterState* s) const {
  s->global_cursor = global_cursor_;
  s->global_queue = global_queue_.ExportState();
}

void GlobalSearchPlanner::ImportState(const ScanEncounterState& s) {
  global_cursor_ = s.global_cursor;
  global_queue_.ImportState(s.global_queue);
}

}  // namespace anchormap
