#include "server/look_back_planner.h"

#include <algorithm>
#include <cmath>
#include <map>
#include <memory>
#include <set>
#include <utility>

#include "common/scan_matching/global_search.h"
#include "common/scan_matching/point_cloud.h"
#include "common/solver/smoother.h"

namespace anchormap {

void LookBackPlanner::LookBackOnGroupChange(const TrajectoryFrames& frames,
                                            const std::deque<PoseKey>& waiting_keys,
                                            int64_t now_utime, const GraphView& graph) {
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
      const EncounterCandidate* hypothesis = qualifier_->BestHypothesis(
          query.solver_id, [&](TrajectoryId x) { return newly_joined(x, y); });
      if (hypothesis == nullptr) continue;
      std::vector<LookBack> pair_looks = LookBacks(*hypothesis, y, waiting_keys, graph);
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
    const Submap& submap = submaps_->Of(look.other)[look.submap];
    const TrajectoryRecord* record = graph.table.FindBySolverId(look.key.trajectory);
    std::shared_ptr<const ScanReference> reference = submaps_->Reference(submap, graph);
    if (record == nullptr || !reference) continue;
    auto query = std::make_shared<const PointCloud>(
        KeyframePoints(*record, look.key.index, options_.max_range_m));
    if (query->empty()) continue;
    // A global search of the submap, as a guided one: the hypothesis chose the submap, not the
    // pose in it, so a match that agrees with the hypothesis is evidence of its own. Not paid
    // from the global searches' tokens (bounded by the cap per group change instead): charged,
    // the searches after it moved by the cap's tokens and FR079 split in three
    // simultaneously joined R3 48 s later, with more searches.
    matches_->Submit(
        look.key, submap.center, /*global=*/true, /*wide=*/false,
        record->utimes[static_cast<size_t>(look.key.index)],
        [reference, query, search] { return GlobalSearch(*reference, *query, search); }, now_utime);
    ++look_backs_;
  }
}

std::vector<LookBackPlanner::LookBack> LookBackPlanner::LookBacks(
    const EncounterCandidate& hypothesis, TrajectoryId other,
    const std::deque<PoseKey>& waiting_keys, const GraphView& graph) {
  const Smoother& smoother = graph.smoother;
  const std::vector<Submap>& submaps = submaps_->Of(other);
  // Oriented with a in the group, b the querying trajectory's keyframe.
  const EncounterCandidate c =
      InOneFrame(smoother, hypothesis.a.trajectory, other) ? hypothesis : Reversed(hypothesis);
  const TrajectoryRecord* record = graph.table.FindBySolverId(c.b.trajectory);
  if (record == nullptr || submaps.empty() || !smoother.HasPose(c.a) || !smoother.HasPose(c.b)) {
    return {};
  }
  std::set<int32_t> waiting;
  for (const PoseKey key : waiting_keys) {
    if (key.trajectory == c.b.trajectory) waiting.insert(key.index);
  }
  // The query trajectory's frame placed in the group's frame by the hypothesis.
  const Pose2 T_global_frame =
      Compose(Compose(smoother.GlobalPose(c.a), c.T_a_b), smoother.FramePose(c.b).Inverse());
  const double reach = options_.near_distance_m + options_.near_wide_max_window_m;
  const double driven_hypothesis = driven_->To(graph.table, c.b);
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
        c.covariance +
        NearDriftOf(std::abs(driven_->To(graph.table, key) - driven_hypothesis), options_) +
        near_->NearWindowDrift(c.a, submaps[nearest->submap].center, graph);
    const double three_sigma = std::min(3.0 * LargestSigma(covariance.topLeftCorner<2, 2>()),
                                        options_.near_wide_max_window_m);
    if (nearest->distance <= options_.near_distance_m + three_sigma) looks.push_back(*nearest);
  }
  return looks;
}

}  // namespace anchormap
