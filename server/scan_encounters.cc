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

Status ScanEncounterOptions::Validate() const {
  if (submap_half_width < 0) return Status::Error("scan.submap_half_width must be >= 0");
  if (submap_stride < 1) return Status::Error("scan.submap_stride must be >= 1");
  if (!(max_range_m > 0)) return Status::Error("scan.max_range_m must be > 0");
  if (global_every < 1) return Status::Error("scan.global_every must be >= 1");
  if (max_global_per_keyframe < 0)
    return Status::Error("scan.max_global_per_keyframe must be >= 0");
  if (max_global_groups_per_keyframe < 0)
    return Status::Error("scan.max_global_groups_per_keyframe must be >= 0");
  if (Status s = global_budget.Validate(); !s.ok()) return s;
  // A keyframe's searches must fit in the bucket, or it would wait for ever.
  if (global_budget.burst < static_cast<double>(max_global_per_keyframe) *
                                static_cast<double>(max_global_groups_per_keyframe)) {
    return Status::Error(
        "scan.global_burst must be >= scan.max_global_per_keyframe x "
        "scan.max_global_groups_per_keyframe");
  }
  if (!(pcm_chi2 > 0) || !(gate_chi2 > 0)) return Status::Error("scan chi2 gates must be > 0");
  if (!(alternative_ratio >= 1)) return Status::Error("scan.alternative_ratio must be >= 1");
  if (!(first_join_hold_s >= 0)) return Status::Error("scan.first_join_hold_s must be >= 0");
  if (pcm_min_separation < 1) return Status::Error("scan.pcm_min_separation must be >= 1");
  if (!(pcm_min_separation_m >= 0)) return Status::Error("scan.pcm_min_separation_m must be >= 0");
  if (!(pcm_max_shared_view > 0 && pcm_max_shared_view <= 1))
    return Status::Error("scan.pcm_max_shared_view must be in (0, 1]");
  if (max_kept < 1) return Status::Error("scan.max_kept must be >= 1");
  if (!(first_join_max_sigma_m > 0) || !(first_join_max_sigma_rad > 0))
    return Status::Error("scan first-join sigmas must be > 0");
  if (!(join_check_radius_m >= 0) || !(join_check_range_m > 0))
    return Status::Error("scan.join_check_radius_m must be >= 0 and join_check_range_m > 0");
  if (!(join_max_conflict >= 0 && join_max_conflict <= 1))
    return Status::Error("scan.join_max_conflict must be in [0, 1]");
  if (!(verify_max_conflict >= 0 && verify_max_conflict <= 1) || verify_min_points < 0 ||
      !(verify_drift_per_m >= 0) || !(verify_drift_rad_per_m >= 0) ||
      !(verify_drift_rad_per_rad >= 0)) {
    return Status::Error(
        "scan map-verified candidates: verify_max_conflict in [0, 1], verify_min_points >= 0, "
        "verify_drift_per_m, verify_drift_rad_per_m and verify_drift_rad_per_rad >= 0");
  }
  if (guide_min_points < 0 || !(guide_max_distance_m >= 0))
    return Status::Error("scan guided search: guide_min_points and guide_max_distance_m >= 0");
  if (look_back_max_per_change < 0)
    return Status::Error("scan.look_back_max_per_change must be >= 0");
  if (!(free_space.resolution_m > 0) || !(free_space.wall_margin_m >= 0))
    return Status::Error("scan free-space grid: resolution_m > 0, wall_margin_m >= 0");
  if (!(near_distance_m >= 0)) return Status::Error("scan.near_distance_m must be >= 0");
  if (!(near_min_overlap >= 0 && near_min_overlap <= 1))
    return Status::Error("scan.near_min_overlap must be in [0, 1]");
  if (near_cooldown_keyframes < 0)
    return Status::Error("scan.near_cooldown_keyframes must be >= 0");
  if (!(near_index_refresh_s >= 0) || !(near_index_slack_m >= 0))
    return Status::Error("scan.near_index_refresh_s and near_index_slack_m must be >= 0");
  if (!(min_window_m > 0) || !(max_window_m >= min_window_m))
    return Status::Error("scan window: 0 < min_window_m <= max_window_m");
  if (!(min_window_rad > 0) || !(max_window_rad >= min_window_rad))
    return Status::Error("scan window: 0 < min_window_rad <= max_window_rad");
  if (!(near_wide_max_window_m >= 0) || near_pair_min_gap < 1 ||
      near_pair_max_gap < near_pair_min_gap || near_max_held < 1) {
    return Status::Error(
        "scan wide near search: near_wide_max_window_m >= 0, 1 <= near_pair_min_gap <= "
        "near_pair_max_gap, near_max_held >= 1");
  }
  if (near_catch_up_every < 0) return Status::Error("scan.near_catch_up_every must be >= 0");
  if (!(near_saturation_m >= 0)) return Status::Error("scan.near_saturation_m must be >= 0");
  if (near_max_partners < 0) return Status::Error("scan.near_max_partners must be >= 0");
  if (!(near_drift_per_m >= 0) || !(near_drift_rad_per_m >= 0))
    return Status::Error("scan near drift: near_drift_per_m and near_drift_rad_per_m >= 0");
  if (!(floor_sigma_m >= 0) || !(floor_sigma_rad >= 0))
    return Status::Error("scan covariance floors must be >= 0");
  if (max_waiting < 1) return Status::Error("scan.max_waiting must be >= 1");
  if (Status s = reference.Validate(); !s.ok()) return s;
  if (Status s = submap_cache.Validate(); !s.ok()) return s;
  if (Status s = near_budget.Validate("scan.near_budget"); !s.ok()) return s;
  return match.Validate();
}

namespace {

// Points of two scans of one trajectory within about this of each other see one wall: the
// estimate between keyframes some metres apart is good to a few centimetres.
constexpr double kSharedViewDistanceM = 0.1;

double LargestSigma(const Eigen::Matrix2d& covariance) {
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d> eigen(covariance);
  return std::sqrt(std::max(0.0, eigen.eigenvalues().maxCoeff()));
}

// The same candidate seen from the other side: a measured in the frame of b.
EncounterCandidate Reversed(const EncounterCandidate& c) {
  EncounterCandidate r = c;
  std::swap(r.a, r.b);
  r.a_is_query = !c.a_is_query;
  Eigen::Matrix3d J;
  r.T_a_b = Between(c.T_a_b, Pose2(), &J, nullptr);
  r.covariance = J * c.covariance * J.transpose();
  return r;
}

// `c` oriented like `like`: its a in the frame of like's a.
EncounterCandidate OrientedLike(const EncounterCandidate& c, const EncounterCandidate& like,
                                const Smoother& smoother) {
  return InOneFrame(smoother, c.a.trajectory, like.a.trajectory) ? c : Reversed(c);
}

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

Eigen::Matrix3d NearDriftOf(double drive_m, const ScanEncounterOptions& options) {
  const double m = options.near_drift_per_m * drive_m;
  const double rad = options.near_drift_rad_per_m * drive_m;
  return Eigen::Vector3d(m * m, m * m, rad * rad).asDiagonal();
}

double NearWindowSaturatingDrive(const ScanEncounterOptions& options) {
  // NearSearchWindow's linear window stops growing at 3 sigma = max(max_window_m,
  // near_wide_max_window_m), its angular one at 3 sigma = max_window_rad; the drift alone
  // reaches both (whatever the prediction's covariance adds) at these drives (a rate of 0: that
  // window does not grow with the drive). The margin keeps rounding from bringing 3 sigma back
  // under the bounds.
  const double linear = std::max(options.max_window_m, options.near_wide_max_window_m);
  const double linear_drive =
      options.near_drift_per_m > 0 ? linear / (3.0 * options.near_drift_per_m) : 0.0;
  const double angular_drive = options.near_drift_rad_per_m > 0
                                   ? options.max_window_rad / (3.0 * options.near_drift_rad_per_m)
                                   : 0.0;
  return std::max(linear_drive, angular_drive) * (1.0 + 1e-6);
}

LocalMatchOptions NearSearchWindow(const Eigen::Matrix3d& covariance,
                                   const ScanEncounterOptions& options, bool* wide) {
  LocalMatchOptions window;
  window.match = options.match;
  const double three_sigma = 3.0 * LargestSigma(covariance.topLeftCorner<2, 2>());
  *wide =
      three_sigma > options.max_window_m && options.near_wide_max_window_m > options.max_window_m;
  window.linear_window_m =
      *wide ? std::min(three_sigma, options.near_wide_max_window_m)
            : std::clamp(three_sigma, options.min_window_m, options.max_window_m);
  // The acceptance bar prunes the branch and bound of a wide window.
  if (*wide) window.match.min_score = std::max(window.match.min_score, options.near_min_score);
  window.angular_window_rad = std::clamp(3.0 * std::sqrt(std::max(0.0, covariance(2, 2))),
                                         options.min_window_rad, options.max_window_rad);
  return window;
}

void ScanEncounters::OnKeyframeAdded(PoseKey key, const GraphView& /*graph*/,
                                     EncounterSourceOutput* /*out*/) {
  waiting_.push_back(key);
  while (static_cast<int>(waiting_.size()) > options_.max_waiting) waiting_.pop_front();
}

std::string ScanEncounters::StatsLine() const {
  return stats_.Summary(name()) + " joins_contradicted " + std::to_string(joins_contradicted_) +
         " global_searches " + std::to_string(global_queue_.searches()) + " global_replaced " +
         std::to_string(global_queue_.dropped()) + " near_saturated " +
         std::to_string(near_saturated_) + " near_capped " + std::to_string(near_capped_) +
         " near_over_budget " + std::to_string(near_budget_.skipped()) + " look_backs " +
         std::to_string(look_backs_) + " " + references_.stats().Summary(name());
}

void ScanEncounters::Poll(int64_t now_utime, const GraphView& graph, EncounterSourceOutput* out) {
  now_utime_ = std::max(now_utime_, now_utime);
  global_queue_.Advance(now_utime_);
  near_budget_.Advance(now_utime_);
  Examine(graph, out);
  JoinQualified(/*flush=*/false, graph, out);
}

void ScanEncounters::Flush(const GraphView& graph, EncounterSourceOutput* out) {
  Examine(graph, out);
  if (graph.covariances != nullptr) UseMatches(/*all=*/true, graph, out);
  JoinQualified(/*flush=*/true, graph, out);
  // The rest is given up, but for the kept candidates of the pairs this output brings into one
  // frame: the server solves the join and flushes once more, and ResolveKept gates them then
  // against the joined estimate, as the next keyframe would after a join mid-run.
  for (auto it = kept_.begin(); it != kept_.end();) {
    if (InOneFrameAfter(graph.smoother, out->constraints, it->first.first, it->first.second)) {
      ++it;
      continue;
    }
    GiveUpHeld(&it->second, &stats_);
    it = kept_.erase(it);
  }
  for (auto& [pair, held] : near_held_) GiveUpHeld(&held, &stats_);
  near_held_.clear();
}

void ScanEncounters::Examine(const GraphView& graph, EncounterSourceOutput* out) {
  if (graph.covariances == nullptr) return;
  ResolveKept(graph, out);
  BuildSubmaps(graph);
  const TrajectoryFrames frames = FramesOf(graph);  // neither step below changes a frame
  CatchUpJoined(frames, graph);
  LookBackOnGroupChange(frames, graph);
  std::deque<PoseKey> still_waiting;
  std::vector<BudgetRequest> ready;
  for (const PoseKey key : waiting_) {
    if (!graph.covariances->HasCovariance(key)) {
      still_waiting.push_back(key);
      continue;
    }
    ready.push_back({key, near_budget_.bounded() ? DrivenTo(key, graph) : 0.0});
  }
  waiting_ = std::move(still_waiting);
  const double most_per_keyframe = options_.near_max_partners > 0
                                       ? options_.near_max_partners
                                       : static_cast<double>(graph.table.records().size());
  const std::vector<PoseKey> skipped =
      near_budget_.Serve(ready, most_per_keyframe, [&](PoseKey key) {
        const int searches = ExamineKeyframe(key, graph, /*near=*/true);
        UseMatches(/*all=*/false, graph, out);
        return static_cast<double>(searches);
      });
  // Over the near budget: their global searches still wait for theirs.
  for (const PoseKey key : skipped) ExamineKeyframe(key, graph, /*near=*/false);
  ServeGlobalQueue(graph);  // tokens accrued since the last keyframe
  UseMatches(/*all=*/false, graph, out);
}

void ScanEncounters::BuildSubmaps(const GraphView& graph) {
  for (const TrajectoryRecord& record : graph.table.records()) {
    std::vector<Submap>& submaps = submaps_[record.solver_id];
    for (;;) {
      const int center =
          options_.submap_half_width + static_cast<int>(submaps.size()) * options_.submap_stride;
      const PoseKey last{record.solver_id, center + options_.submap_half_width};
      if (last.index >= record.num_keyframes() || !graph.covariances->HasCovariance(last)) break;
      Submap submap;
      submap.center = PoseKey{record.solver_id, center};
      submap.drawing = DrawKeyframeSubmap(record, graph.smoother, submap.center,
                                          options_.submap_half_width, options_.max_range_m);
      submaps.push_back(std::move(submap));
    }
  }
}

std::shared_ptr<const ScanReference> ScanEncounters::Reference(const Submap& submap,
                                                               const GraphView& graph) {
  const TrajectoryRecord* record = graph.table.FindBySolverId(submap.center.trajectory);
  if (record == nullptr) return nullptr;
  return references_.Get(*record, submap.drawing, options_.submap_half_width);
}

int ScanEncounters::ExamineKeyframe(PoseKey key, const GraphView& graph, bool near_too) {
  const TrajectoryRecord* record = graph.table.FindBySolverId(key.trajectory);
  if (record == nullptr || key.index >= record->num_keyframes()) return 0;
  if (record->scans[static_cast<size_t>(key.index)].ranges.empty()) return 0;
  bool unjoined = false;
  std::vector<NearTarget> near;
  for (const TrajectoryRecord& other : graph.table.records()) {
    if (other.solver_id == key.trajectory) continue;
    if (InOneFrame(graph.smoother, key.trajectory, other.solver_id)) {
      if (!near_too) continue;
      if (std::optional<NearTarget> target = FindNear(key, other.solver_id, graph)) {
        near.push_back(*target);
      }
    } else {
      unjoined = true;
    }
  }
  std::sort(near.begin(), near.end(), [](const NearTarget& x, const NearTarget& y) {
    return x.distance != y.distance ? x.distance < y.distance : x.other < y.other;
  });
  if (options_.near_max_partners > 0 &&
      near.size() > static_cast<size_t>(options_.near_max_partners)) {
    near_capped_ += static_cast<int64_t>(near.size()) - options_.near_max_partners;
    near.resize(static_cast<size_t>(options_.near_max_partners));
  }
  int searches = 0;
  for (const NearTarget& target : near) searches += SearchNear(key, target, graph) ? 1 : 0;
  if (unjoined && key.index % options_.global_every == 0) {
    global_queue_.Enqueue(key);
    ServeGlobalQueue(graph);
  }
  return searches;
}

ScanEncounters::TrajectoryFrames ScanEncounters::FramesOf(const GraphView& graph) {
  TrajectoryFrames frames;
  frames.reserve(graph.table.records().size());
  for (const TrajectoryRecord& record : graph.table.records()) {
    frames.emplace_back(record.solver_id, FrameOf(graph.smoother, record.solver_id));
  }
  return frames;
}

void ScanEncounters::CatchUpJoined(const TrajectoryFrames& frames, const GraphView& graph) {
  const std::deque<TrajectoryRecord>& records = graph.table.records();
  // The same frames as at the last call: every pair in one frame is in near_joined_ already.
  if (frames == caught_up_frames_) {
    near_joined_known_ = true;
    return;
  }
  caught_up_frames_ = frames;
  std::set<std::pair<int64_t, int32_t>> waiting;
  for (const PoseKey key : waiting_) waiting.emplace(key.trajectory.value(), key.index);
  for (size_t i = 0; i < records.size(); ++i) {
    for (size_t j = i + 1; j < records.size(); ++j) {
      const TrajectoryId a = std::min(records[i].solver_id, records[j].solver_id);
      const TrajectoryId b = std::max(records[i].solver_id, records[j].solver_id);
      if (!InOneFrame(graph.smoother, a, b) || !near_joined_.insert({a, b}).second) continue;
      if (!near_joined_known_ || options_.near_catch_up_every < 1) continue;
      for (const auto& [from, to] : {std::make_pair(a, b), std::make_pair(b, a)}) {
        const TrajectoryRecord* record = graph.table.FindBySolverId(from);
        for (int32_t k = 0; k < record->num_keyframes(); k += options_.near_catch_up_every) {
          const PoseKey key{from, k};
          // Waiting keyframes are examined next, as joined ones.
          if (waiting.count({from.value(), k}) > 0 || !graph.covariances->HasCovariance(key) ||
              record->scans[static_cast<size_t>(k)].ranges.empty()) {
            continue;
          }
          if (std::optional<NearTarget> target = FindNear(key, to, graph)) {
            SearchNear(key, *target, graph);
          }
        }
      }
    }
  }
  near_joined_known_ = true;
}

void ScanEncounters::ServeGlobalQueue(const GraphView& graph) {
  const int most_per_target = std::max(0, options_.max_global_per_keyframe);
  for (std::optional<PoseKey> key = global_queue_.Next(); key; key = global_queue_.Next()) {
    const std::vector<GlobalTarget> targets = GlobalTargets(*key, graph);
    int cost = 0;
    for (const GlobalTarget& target : targets) {
      cost += static_cast<int>(
          std::min(submaps_[target.other].size(), static_cast<size_t>(most_per_target)));
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
    const auto submaps = submaps_.find(id);
    if (submaps == submaps_.end() || submaps->second.empty()) continue;
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
  const auto submaps = submaps_.find(other);
  if (submaps == submaps_.end()) return 0;
  return std::min(submaps->second.size(),
                  static_cast<size_t>(std::max(0, options_.max_global_per_keyframe)));
}

int ScanEncounters::SearchGlobally(PoseKey key, const GlobalTarget& target,
                                   const GraphView& graph) {
  const TrajectoryId other = target.other;
  std::vector<Submap>& submaps = submaps_[other];
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
    std::shared_ptr<const ScanReference> reference = Reference(submap, graph);
    if (!reference) continue;
    Submit(key, submap.center, /*global=*/true, /*wide=*/false,
           record->utimes[static_cast<size_t>(key.index)],
           [reference, query, search] { return GlobalSearch(*reference, *query, search); });
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
  const auto submaps = submaps_.find(other);
  if (options_.guide_max_distance_m <= 0 || submaps == submaps_.end() || most == 0) return {};
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
  const Kept* best = BestHypothesis(
      key.trajectory, [&](TrajectoryId id) { return InOneFrame(smoother, id, other); });
  if (best == nullptr) return {};
  return GuidedByHypothesis(key, best->candidate, submaps->second, graph, most, nearest_m);
}

const ScanEncounters::Kept* ScanEncounters::BestHypothesis(
    TrajectoryId query, const std::function<bool(TrajectoryId)>& accept) const {
  const Kept* best = nullptr;
  for (const auto& [pair, kept] : kept_) {
    const bool first = pair.first == query;
    if (!first && pair.second != query) continue;
    if (!accept(first ? pair.second : pair.first)) continue;
    for (const Kept& k : kept) {
      if (!k.localised || k.conflict_points < options_.guide_min_points ||
          k.conflict > options_.verify_max_conflict) {
        continue;
      }
      if (best == nullptr || k.conflict < best->conflict) best = &k;
    }
  }
  return best;
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
      const Kept* hypothesis =
          BestHypothesis(query.solver_id, [&](TrajectoryId x) { return newly_joined(x, y); });
      if (hypothesis == nullptr) continue;
      std::vector<LookBack> pair_looks = LookBacks(hypothesis->candidate, y, graph);
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
    const Submap& submap = submaps_[look.other][look.submap];
    const TrajectoryRecord* record = graph.table.FindBySolverId(look.key.trajectory);
    std::shared_ptr<const ScanReference> reference = Reference(submap, graph);
    if (record == nullptr || !reference) continue;
    auto query = std::make_shared<const PointCloud>(
        KeyframePoints(*record, look.key.index, options_.max_range_m));
    if (query->empty()) continue;
    // A global search of the submap, as a guided one: the hypothesis chose the submap, not the
    // pose in it, so a match that agrees with the hypothesis is evidence of its own. Not paid
    // from the global searches' tokens (bounded by the cap per group change instead): charged,
    // the searches after it moved by the cap's tokens and FR079 split in three
    // simultaneously joined R3 48 s later, with more searches.
    Submit(
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
  const std::vector<Submap>& submaps = submaps_[other];
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

std::optional<ScanEncounters::NearTarget> ScanEncounters::FindNear(PoseKey key, TrajectoryId other,
                                                                   const GraphView& graph) {
  if (options_.near_distance_m <= 0) return std::nullopt;
  const auto quiet = near_quiet_until_.find({key.trajectory, other});
  if (quiet != near_quiet_until_.end() && key.index < quiet->second) return std::nullopt;
  std::vector<Submap>& submaps = submaps_[other];
  if (submaps.empty()) return std::nullopt;
  const Pose2 global_key = graph.smoother.GlobalPose(key);
  // The keyframe in the other's frame (one rigid motion: the distances are the same).
  const PoseKey reference_center = submaps.front().center;
  const Pose2 T_frame_key = Compose(Compose(graph.smoother.FramePose(reference_center),
                                            graph.smoother.GlobalPose(reference_center).Inverse()),
                                    global_key);
  const std::vector<int32_t> near =
      NearIndex(other, graph)
          .Near(T_frame_key.translation(), options_.near_distance_m + options_.near_index_slack_m);
  std::optional<NearTarget> nearest;
  for (const int32_t item : near) {
    const Submap& submap = submaps[static_cast<size_t>(item)];
    if (submap.drawing.num_points == 0) continue;
    const double distance =
        (graph.smoother.GlobalPose(submap.center).translation() - global_key.translation()).norm();
    if (!nearest || distance < nearest->distance) {
      nearest = NearTarget{other, static_cast<size_t>(item), distance};
    }
  }
  if (!nearest || nearest->distance > options_.near_distance_m) return std::nullopt;
  if (Saturated(key, submaps[nearest->submap].center, graph)) {
    ++near_saturated_;
    return std::nullopt;
  }
  return nearest;
}

bool ScanEncounters::Saturated(PoseKey key, PoseKey center, const GraphView& graph) {
  if (graph.ties == nullptr || options_.near_saturation_m <= 0) return false;
  const auto driven_to = [this, &graph](PoseKey k) { return DrivenTo(k, graph); };
  return graph.ties->DriveBelow(key, center, driven_to, options_.near_saturation_m);
}

bool ScanEncounters::SearchNear(PoseKey key, const NearTarget& target, const GraphView& graph) {
  const Submap& nearest = submaps_[target.other][target.submap];
  const std::optional<PredictedRelativePose> predicted =
      PredictRelativePose(graph.covariances, nearest.center, key);
  if (!predicted) return false;
  const TrajectoryRecord* record = graph.table.FindBySolverId(key.trajectory);
  auto query =
      std::make_shared<const PointCloud>(KeyframePoints(*record, key.index, options_.max_range_m));
  bool wide = false;
  LocalMatchOptions window = NearSearchWindow(
      predicted->covariance + NearWindowDrift(nearest.center, key, graph), options_, &wide);
  window.match.covariance_min_score = options_.near_min_score;  // UseMatches' bars
  window.match.covariance_min_overlap = options_.near_min_overlap;
  std::shared_ptr<const ScanReference> reference = Reference(nearest, graph);
  if (!reference) return false;
  const Pose2 guess = predicted->T_a_b;
  Submit(
      key, nearest.center, /*global=*/false, wide, record->utimes[static_cast<size_t>(key.index)],
      [reference, query, guess, window] { return MatchLocal(*reference, *query, guess, window); });
  return true;
}

const PositionIndex& ScanEncounters::NearIndex(TrajectoryId other, const GraphView& graph) {
  const std::vector<Submap>& submaps = submaps_[other];
  SubmapIndex& entry = near_index_[other];
  const SmootherStats& stats = graph.smoother.stats();
  const int64_t merges = stats.batch_steps_on_merge + stats.partial_merges;
  const bool due =
      entry.merges != merges || 1e-6 * static_cast<double>(now_utime_ - entry.refreshed_utime) >=
                                    options_.near_index_refresh_s;
  if (due) {
    entry.index.Clear();
    entry.indexed = 0;
    entry.refreshed_utime = now_utime_;
    entry.merges = merges;
  }
  for (; entry.indexed < submaps.size(); ++entry.indexed) {
    entry.index.Add(static_cast<int32_t>(entry.indexed),
                    graph.smoother.FramePose(submaps[entry.indexed].center).translation());
  }
  return entry.index;
}

void ScanEncounters::Submit(PoseKey key, PoseKey center, bool global, bool wide, int64_t key_utime,
                            MatchPool::Job job, std::optional<int64_t> due_from_utime) {
  PendingMatch pending;
  pending.key = key;
  pending.center = center;
  pending.global = global;
  pending.wide = wide;
  pending.key_utime = key_utime;
  pending.due_utime = pool_ ? schedule_.DueUtime(due_from_utime.value_or(key_utime))
                            : std::numeric_limits<int64_t>::min();
  pending.result =
      RunMatch(pool_, MatchTag{key, center, global ? MatchKind::kScanGlobal : MatchKind::kScanNear},
               std::move(job));
  matches_.push_back(std::move(pending));
}

void ScanEncounters::UseMatches(bool all, const GraphView& graph, EncounterSourceOutput* out) {
  // A keyframe that joined two trajectories by one global match is not searched further
  // against that trajectory (its other submaps' matches are dropped unused).
  std::optional<std::pair<PoseKey, TrajectoryId>> joined;
  while (!matches_.empty() && (all || matches_.front().due_utime <= now_utime_)) {
    const PendingMatch pending = std::move(matches_.front());
    matches_.pop_front();
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
      OfferNearMatch(candidate, pending.wide, graph, out);
    }
  }
}

double ScanEncounters::DrivenTo(PoseKey key, const GraphView& graph) {
  const TrajectoryRecord* record = graph.table.FindBySolverId(key.trajectory);
  return record != nullptr ? driven_.To(*record, key.index) : 0.0;
}

Eigen::Matrix3d ScanEncounters::NearDrift(PoseKey a, PoseKey b, const GraphView& graph) {
  if (graph.ties == nullptr ||
      (options_.near_drift_per_m <= 0 && options_.near_drift_rad_per_m <= 0)) {
    return Eigen::Matrix3d::Zero();
  }
  const auto driven_to = [this, &graph](PoseKey key) { return DrivenTo(key, graph); };
  // Exact, or (the search's cap) the least the drive can be: a stricter gate, never a looser.
  const double drive = graph.ties->Drive(a, b, driven_to).at_least;
  if (!std::isfinite(drive)) return Eigen::Matrix3d::Zero();
  return NearDriftOf(drive, options_);
}

Eigen::Matrix3d ScanEncounters::NearWindowDrift(PoseKey a, PoseKey b, const GraphView& graph) {
  if (graph.ties == nullptr ||
      (options_.near_drift_per_m <= 0 && options_.near_drift_rad_per_m <= 0)) {
    return Eigen::Matrix3d::Zero();
  }
  const double saturated = NearWindowSaturatingDrive(options_);
  const auto driven_to = [this, &graph](PoseKey key) { return DrivenTo(key, graph); };
  // Exact, or (the search's cap) the most the drive can be: a wider window, never a narrower.
  const double drive = graph.ties->Drive(a, b, driven_to, saturated).at_most;
  if (drive <= saturated) return NearDriftOf(drive, options_);
  if (!graph.ties->Connected(a.trajectory, b.trajectory)) return Eigen::Matrix3d::Zero();
  // Farther than `saturated`: any such drive gives the widest window, this one too.
  return NearDriftOf(saturated, options_);
}

void ScanEncounters::OfferNearMatch(const EncounterCandidate& candidate, bool wide,
                                    const GraphView& graph, EncounterSourceOutput* out) {
  const Pair key{candidate.b.trajectory, candidate.a.trajectory};
  // Within the estimate's own covariance: enters at once.
  if (!wide && WithinGate(candidate, graph, /*widened=*/false, Eigen::Matrix3d::Zero())) {
    ++stats_.accepted;
    Emit(candidate, out);
    near_quiet_until_[key] = candidate.b.index + 1 + options_.near_cooldown_keyframes;
    return;
  }
  // Only now: the drive through the ties is a search of the tie graph.
  const Eigen::Matrix3d drift = NearDrift(candidate.a, candidate.b, graph);
  if ((!wide && drift.isZero()) || !WithinGate(candidate, graph, wide, drift)) {
    ++stats_.gate_rejected;
    return;
  }
  HoldForPair(candidate, graph, out);
}

void ScanEncounters::HoldForPair(const EncounterCandidate& candidate, const GraphView& graph,
                                 EncounterSourceOutput* out) {
  const Pair key{candidate.b.trajectory, candidate.a.trajectory};
  std::deque<EncounterCandidate>& held = near_held_[key];
  GiveUpHeldOlderThan(
      candidate.b.index, options_.near_pair_max_gap,
      [](const EncounterCandidate& c) { return c.b.index; }, &held, &stats_);
  for (auto it = held.rbegin(); it != held.rend(); ++it) {
    if (candidate.b.index - it->b.index < options_.near_pair_min_gap) continue;
    if (!Consistent(*it, candidate, graph, /*drift=*/false)) continue;
    const EncounterCandidate first = *it;
    DropHeld(&held, &stats_);
    stats_.accepted += 2;
    Emit(first, out);
    Emit(candidate, out);
    near_quiet_until_[key] = candidate.b.index + 1 + options_.near_cooldown_keyframes;
    return;
  }
  Hold(candidate, options_.near_max_held, &held, &stats_);
}

void ScanEncounters::OfferCandidate(const EncounterCandidate& offered, const GraphView& graph,
                                    EncounterSourceOutput* out) {
  if (graph.covariances == nullptr || offered.a.trajectory == offered.b.trajectory) return;
  if (InOneFrame(graph.smoother, offered.a.trajectory, offered.b.trajectory)) {
    GateAndEmit(offered, graph, out);
    return;
  }
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
    qualified_since_.emplace(pair, now_utime_);
  }
  offered_kept.support = confirmed;
  kept.push_back(offered_kept);
  ++stats_.kept;
  if (static_cast<int>(kept.size()) > options_.max_kept) {
    kept.pop_front();
    --stats_.kept;
    ++stats_.unconfirmed;
  }
}

bool ScanEncounters::Localised(const EncounterCandidate& candidate) const {
  return LargestSigma(candidate.covariance.topLeftCorner<2, 2>()) <=
             options_.first_join_max_sigma_m &&
         std::sqrt(std::max(0.0, candidate.covariance(2, 2))) <= options_.first_join_max_sigma_rad;
}

bool ScanEncounters::Consistent(const EncounterCandidate& c1, const EncounterCandidate& c2,
                                const GraphView& graph, bool drift) {
  return PairwiseChi2(c1, c2, graph, drift ? options_.verify_drift_per_m : 0.0,
                      drift ? options_.verify_drift_rad_per_m : 0.0,
                      drift ? options_.verify_drift_rad_per_rad : 0.0) <= options_.pcm_chi2;
}

double ScanEncounters::PairwiseChi2(const EncounterCandidate& c1, const EncounterCandidate& c2,
                                    const GraphView& graph, double drift_per_m,
                                    double drift_rad_per_m, double drift_rad_per_rad) {
  // Within each trajectory, the estimate from c1's keyframe to c2's, with covariance.
  std::optional<PredictedRelativePose> in_a = PredictRelativePose(graph.covariances, c1.a, c2.a);
  std::optional<PredictedRelativePose> in_b = PredictRelativePose(graph.covariances, c1.b, c2.b);
  if (!in_a || !in_b) return std::numeric_limits<double>::infinity();
  if (drift_per_m > 0 || drift_rad_per_m > 0 || drift_rad_per_rad > 0) {
    const auto widen = [&](PoseKey k1, PoseKey k2, PredictedRelativePose* predicted) {
      // In two trajectories of one group (across pairs) no drive: the joint estimate between
      // them rests on their ties, not on odometry alone (ACES split in three sequentially: 125 m
      // through the ties widened the heading by 0.125 rad and let R1[235]-R3[50], 0.2 rad off,
      // confirm the true R2[65]-R3[125]; chi-square 2.8 with the drive, 79 without).
      const double driven = k1.trajectory == k2.trajectory
                                ? std::abs(DrivenTo(k2, graph) - DrivenTo(k1, graph))
                                : 0.0;
      const double m = drift_per_m * driven;
      // The estimate's turn between them (wrapped: a full spin counts as none, the safe side).
      const double rad =
          drift_rad_per_m * driven + drift_rad_per_rad * std::abs(predicted->T_a_b.theta());
      predicted->covariance += Eigen::Vector3d(m * m, m * m, rad * rad).asDiagonal();
    };
    widen(c1.a, c2.a, &*in_a);
    widen(c1.b, c2.b, &*in_b);
  }
  return PairwiseInconsistency2(*in_a, c1.T_a_b, c1.covariance, *in_b, c2.T_a_b, c2.covariance);
}

JoinConflict ScanEncounters::OwnMapsConflict(const EncounterCandidate& candidate,
                                             const GraphView& graph) const {
  const TrajectoryRecord* record_a = graph.table.FindBySolverId(candidate.a.trajectory);
  const TrajectoryRecord* record_b = graph.table.FindBySolverId(candidate.b.trajectory);
  if (record_a == nullptr || record_b == nullptr) return {};
  return MeasureCandidateConflict(*record_a, *record_b, graph.smoother, candidate.a, candidate.b,
                                  candidate.T_a_b, options_.join_check_radius_m,
                                  options_.join_check_range_m, options_.free_space);
}

bool ScanEncounters::MapsAgree(const JoinConflict& conflict) const {
  return conflict.fewer_seen() >= static_cast<size_t>(options_.verify_min_points) &&
         conflict.pooled_fraction() <= options_.verify_max_conflict;
}

bool ScanEncounters::ApartAndSeeingOtherWalls(PoseKey k1, PoseKey k2,
                                              const GraphView& graph) const {
  return std::abs(k1.index - k2.index) >= 2 * options_.submap_half_width + 1 &&
         Apart(k1, k2, graph) && SharedView(k1, k2, graph) < options_.pcm_max_shared_view;
}

bool ScanEncounters::Apart(PoseKey x, PoseKey y, const GraphView& graph) const {
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

double ScanEncounters::SharedView(PoseKey x, PoseKey y, const GraphView& graph) const {
  const TrajectoryRecord* record_x = graph.table.FindBySolverId(x.trajectory);
  const TrajectoryRecord* record_y = graph.table.FindBySolverId(y.trajectory);
  if (record_x == nullptr || record_y == nullptr) return 1.0;
  return x.trajectory == y.trajectory
             ? KeyframeOverlap(*record_x, graph.smoother, x.index, y.index, options_.max_range_m,
                               kSharedViewDistanceM)
             : KeyframeOverlap(*record_x, x.index, *record_y, y.index, graph.smoother,
                               options_.max_range_m, kSharedViewDistanceM);
}

bool ScanEncounters::TwoPlaces(const EncounterCandidate& c1, const EncounterCandidate& c2,
                               const GraphView& graph) const {
  // A robot that turns round, or drives on along one corridor, keeps seeing the same walls:
  // what both trajectories see twice is one piece of evidence, however far apart.
  return Apart(c1.a, c2.a, graph) && Apart(c1.b, c2.b, graph) &&
         (SharedView(c1.a, c2.a, graph) < options_.pcm_max_shared_view ||
          SharedView(c1.b, c2.b, graph) < options_.pcm_max_shared_view);
}

bool ScanEncounters::Independent(const Kept& k1, const Kept& k2, const GraphView& graph) const {
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

std::vector<ScanEncounters::Pair> ScanEncounters::PairsBetweenTheSameGroups(
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

bool ScanEncounters::IndependentAcross(const Kept& k1, const Kept& k2,
                                       const GraphView& graph) const {
  if (SamePair(k1.candidate, k2.candidate)) return Independent(k1, k2, graph);
  // Only map-verified evidence: a pair of groups offers more ways for aliases to agree.
  if (!k1.localised || !k2.localised || !k1.verified || !k2.verified) return false;
  return TwoPlaces(k1.candidate, OrientedLike(k2.candidate, k1.candidate, graph.smoother), graph);
}

bool ScanEncounters::ConsistentAcross(const EncounterCandidate& c1, const EncounterCandidate& c2,
                                      const GraphView& graph) {
  return Consistent(c1, OrientedLike(c2, c1, graph.smoother), graph, /*drift=*/true);
}

void ScanEncounters::JoinQualified(bool flush, const GraphView& graph, EncounterSourceOutput* out) {
  for (auto it = qualified_since_.begin(); it != qualified_since_.end();) {
    const Pair pair = it->first;
    const bool joined = InOneFrame(graph.smoother, pair.first, pair.second);
    const bool due =
        1e-6 * static_cast<double>(now_utime_ - it->second) >= options_.first_join_hold_s;
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
          Emit(k.candidate, out);
          ++stats_.accepted;
          --stats_.kept;
        } else {
          rest.push_back(k);
        }
      }
      pair_kept = std::move(rest);
    }
  }
}

bool ScanEncounters::MapsContradict(const std::vector<Kept*>& set, const GraphView& graph) const {
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

void ScanEncounters::ResolveKept(const GraphView& graph, EncounterSourceOutput* out) {
  for (auto it = kept_.begin(); it != kept_.end();) {
    if (!InOneFrame(graph.smoother, it->first.first, it->first.second)) {
      ++it;
      continue;
    }
    for (const Kept& k : it->second) {
      --stats_.kept;
      GateAndEmit(k.candidate, graph, out);
    }
    it = kept_.erase(it);
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
  const std::optional<PredictedRelativePose> predicted =
      PredictRelativePose(graph.covariances, candidate.a, candidate.b);
  if (!predicted) return false;
  Eigen::Matrix3d covariance = predicted->covariance;
  if (widened) {
    // In every direction by the largest sigma: the estimate of two drifted-apart
    // trajectories is off along axes its covariance does not know.
    const double sigma = LargestSigma(covariance.topLeftCorner<2, 2>());
    covariance.topLeftCorner<2, 2>() += sigma * sigma * Eigen::Matrix2d::Identity();
  }
  return Mahalanobis2(predicted->T_a_b, candidate.T_a_b,
                      covariance + drift + candidate.covariance) <= options_.gate_chi2;
}

bool ScanEncounters::GateAndEmit(const EncounterCandidate& candidate, const GraphView& graph,
                                 EncounterSourceOutput* out) {
  if (!PassesGate(candidate, graph, /*widened=*/false)) return false;
  ++stats_.accepted;
  Emit(candidate, out);
  return true;
}

void ScanEncounters::Emit(const EncounterCandidate& candidate, EncounterSourceOutput* out) {
  EncounterConstraint constraint;
  constraint.a = candidate.a;
  constraint.b = candidate.b;
  constraint.measured_T_a_b = candidate.T_a_b;
  constraint.covariance = candidate.covariance;
  constraint.utime = candidate.utime;
  constraint.source = name();
  constraint.kind = ConstraintKind::kScanEncounter;
  out->constraints.push_back(constraint);
}

}  // namespace anchormap
