#include "server/near_search.h"

#include <algorithm>
#include <cmath>
#include <memory>
#include <set>
#include <utility>

#include "common/scan_matching/point_cloud.h"
#include "common/solver/smoother.h"
#include "server/held_matches.h"
#include "server/relative_pose.h"

namespace anchormap {

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
  // The acceptance bar prunes the branch and bound (UseMatches drops a lattice score under
  // near_min_score): a plain window finds every score it keeps, a wide one those above it.
  window.match.min_score = *wide ? std::max(window.match.min_score, options.near_min_score)
                                 : LatticeBarFor(options.near_min_score, window.match.min_score);
  window.angular_window_rad = std::clamp(3.0 * std::sqrt(std::max(0.0, covariance(2, 2))),
                                         options.min_window_rad, options.max_window_rad);
  return window;
}

std::vector<NearSearch::NearTarget> NearSearch::Targets(PoseKey key, const GraphView& graph) {
  std::vector<NearTarget> near;
  for (const TrajectoryRecord& other : graph.table.records()) {
    if (other.solver_id == key.trajectory) continue;
    if (InOneFrame(graph.smoother, key.trajectory, other.solver_id)) {
      if (std::optional<NearTarget> target = FindNear(key, other.solver_id, graph)) {
        near.push_back(*target);
      }
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
  return near;
}

std::optional<NearSearch::NearTarget> NearSearch::FindNear(PoseKey key, TrajectoryId other,
                                                           const GraphView& graph) {
  if (options_.near_distance_m <= 0) return std::nullopt;
  const auto quiet = near_quiet_until_.find({key.trajectory, other});
  if (quiet != near_quiet_until_.end() && key.index < quiet->second) return std::nullopt;
  std::vector<Submap>& submaps = submaps_->Of(other);
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

bool NearSearch::Saturated(PoseKey key, PoseKey center, const GraphView& graph) {
  if (graph.ties == nullptr || options_.near_saturation_m <= 0) return false;
  const auto driven_to = [this, &graph](PoseKey k) { return driven_->To(graph.table, k); };
  return graph.ties->DriveBelow(key, center, driven_to, options_.near_saturation_m);
}

bool NearSearch::SearchNear(PoseKey key, const NearTarget& target, const GraphView& graph) {
  const Submap& nearest = submaps_->Of(target.other)[target.submap];
  // Whether the pair can be predicted at all, before the drive's tie search (no solve yet).
  const auto at_once = [](const Pose2&, const Eigen::Matrix3d&) { return true; };
  if (!PredictRelativePose(graph.covariances, nearest.center, key, at_once)) return false;
  const Eigen::Matrix3d drift = NearWindowDrift(nearest.center, key, graph);
  // The window only widens as the predicted covariance grows: once a partial sum of its
  // solve (a lower bound) with the drift gives the widest window in both axes, the exact
  // covariance gives it too, bit for bit, and the rest of the solve is not needed.
  const auto widest = [&](const Pose2&, const Eigen::Matrix3d& so_far) {
    bool wide = false;
    const LocalMatchOptions at = NearSearchWindow(so_far + drift, options_, &wide);
    return wide && at.linear_window_m == options_.near_wide_max_window_m &&
           at.angular_window_rad == options_.max_window_rad;
  };
  const std::optional<PredictedRelativePose> predicted =
      PredictRelativePose(graph.covariances, nearest.center, key, widest);
  if (!predicted) return false;
  const TrajectoryRecord* record = graph.table.FindBySolverId(key.trajectory);
  auto query =
      std::make_shared<const PointCloud>(KeyframePoints(*record, key.index, options_.max_range_m));
  bool wide = false;
  LocalMatchOptions window = NearSearchWindow(predicted->covariance + drift, options_, &wide);
  window.match.covariance_min_score = options_.near_min_score;  // UseMatches' bars
  window.match.covariance_min_overlap = options_.near_min_overlap;
  std::shared_ptr<const ScanReference> reference = submaps_->Reference(nearest, graph);
  if (!reference) return false;
  const Pose2 guess = predicted->T_a_b;
  matches_->Submit(
      key, nearest.center, /*global=*/false, wide, record->utimes[static_cast<size_t>(key.index)],
      [reference, query, guess, window] { return MatchLocal(*reference, *query, guess, window); });
  return true;
}

const PositionIndex& NearSearch::NearIndex(TrajectoryId other, const GraphView& graph) {
  const std::vector<Submap>& submaps = submaps_->Of(other);
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

void NearSearch::CatchUpJoined(const TrajectoryFrames& frames,
                               const std::deque<PoseKey>& waiting_keys, const GraphView& graph) {
  const std::deque<TrajectoryRecord>& records = graph.table.records();
  // The same frames as at the last call: every pair in one frame is in near_joined_ already.
  if (frames == caught_up_frames_) {
    near_joined_known_ = true;
    return;
  }
  caught_up_frames_ = frames;
  std::set<std::pair<int64_t, int32_t>> waiting;
  for (const PoseKey key : waiting_keys) waiting.emplace(key.trajectory.value(), key.index);
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

Eigen::Matrix3d NearSearch::NearDrift(PoseKey a, PoseKey b, const GraphView& graph) {
  if (graph.ties == nullptr ||
      (options_.near_drift_per_m <= 0 && options_.near_drift_rad_per_m <= 0)) {
    return Eigen::Matrix3d::Zero();
  }
  const auto driven_to = [this, &graph](PoseKey key) { return driven_->To(graph.table, key); };
  // Exact, or (the search's cap) the least the drive can be: a stricter gate, never a looser.
  const double drive = graph.ties->Drive(a, b, driven_to).at_least;
  if (!std::isfinite(drive)) return Eigen::Matrix3d::Zero();
  return NearDriftOf(drive, options_);
}

Eigen::Matrix3d NearSearch::NearWindowDrift(PoseKey a, PoseKey b, const GraphView& graph) {
  if (graph.ties == nullptr ||
      (options_.near_drift_per_m <= 0 && options_.near_drift_rad_per_m <= 0)) {
    return Eigen::Matrix3d::Zero();
  }
  const double saturated = NearWindowSaturatingDrive(options_);
  const auto driven_to = [this, &graph](PoseKey key) { return driven_->To(graph.table, key); };
  // Exact, or (the search's cap) the most the drive can be: a wider window, never a narrower.
  const double drive = graph.ties->Drive(a, b, driven_to, saturated).at_most;
  if (drive <= saturated) return NearDriftOf(drive, options_);
  if (!graph.ties->Connected(a.trajectory, b.trajectory)) return Eigen::Matrix3d::Zero();
  // Farther than `saturated`: any such drive gives the widest window, this one too.
  return NearDriftOf(saturated, options_);
}

void NearSearch::OfferNearMatch(const EncounterCandidate& candidate, bool wide,
                                const GraphView& graph, EncounterSourceOutput* out) {
  const Pair key{candidate.b.trajectory, candidate.a.trajectory};
  // Within the estimate's own covariance: enters at once.
  if (!wide && WithinGate(candidate, graph, /*widened=*/false, Eigen::Matrix3d::Zero(), options_)) {
    ++stats_->accepted;
    Emit(candidate, source_name_, out);
    near_quiet_until_[key] = candidate.b.index + 1 + options_.near_cooldown_keyframes;
    return;
  }
  // Only now: the drive through the ties is a search of the tie graph.
  const Eigen::Matrix3d drift = NearDrift(candidate.a, candidate.b, graph);
  if ((!wide && drift.isZero()) || !WithinGate(candidate, graph, wide, drift, options_)) {
    ++stats_->gate_rejected;
    return;
  }
  HoldForPair(candidate, graph, out);
}

void NearSearch::HoldForPair(const EncounterCandidate& candidate, const GraphView& graph,
                             EncounterSourceOutput* out) {
  const Pair key{candidate.b.trajectory, candidate.a.trajectory};
  std::deque<EncounterCandidate>& held = near_held_[key];
  const auto driven_to = [this, &graph](PoseKey k) { return driven_->To(graph.table, k); };
  GiveUpHeldOlderThan(
      candidate.b.index, options_.near_pair_max_gap,
      [](const EncounterCandidate& c) { return c.b.index; }, &held, stats_);
  for (auto it = held.rbegin(); it != held.rend(); ++it) {
    if (candidate.b.index - it->b.index < options_.near_pair_min_gap) continue;
    if (PairwiseChi2(*it, candidate, graph, driven_to, 0.0, 0.0, 0.0) > options_.pcm_chi2) continue;
    const EncounterCandidate first = *it;
    DropHeld(&held, stats_);
    stats_->accepted += 2;
    Emit(first, source_name_, out);
    Emit(candidate, source_name_, out);
    near_quiet_until_[key] = candidate.b.index + 1 + options_.near_cooldown_keyframes;
    return;
  }
  Hold(candidate, options_.near_max_held, &held, stats_);
}

void NearSearch::GiveUpHeld() {
  for (auto& [pair, held] : near_held_) anchormap::GiveUpHeld(&held, stats_);
  near_held_.clear();
}

void NearSearch::ExportState(ScanEncounterState* s) const {
  s->near_quiet_until = near_quiet_until_;
  for (const auto& [trajectory, entry] : near_index_) {
    s->near_index[trajectory] = {entry.index.Entries(), entry.indexed, entry.refreshed_utime,
                                 entry.merges};
  }
  s->near_budget = near_budget_.ExportState();
  for (const auto& [pair, held] : near_held_) {
    auto& out = s->near_held[pair];
    for (const EncounterCandidate& c : held) out.push_back(ToState(c));
  }
  s->near_joined = near_joined_;
  s->near_joined_known = near_joined_known_;
}

void NearSearch::ImportState(const ScanEncounterState& s) {
  now_utime_ = s.now_utime;
  near_quiet_until_ = s.near_quiet_until;
  near_index_.clear();
  for (const auto& [trajectory, entry] : s.near_index) {
    SubmapIndex& out = near_index_[trajectory];
    for (const auto& [item, position] : entry.entries) out.index.Add(item, position);
    out.indexed = entry.indexed;
    out.refreshed_utime = entry.refreshed_utime;
    out.merges = entry.merges;
  }
  if (s.near_budget) near_budget_.ImportState(*s.near_budget);
  near_held_.clear();
  for (const auto& [pair, held] : s.near_held) {
    std::deque<EncounterCandidate>& out = near_held_[pair];
    for (const ScanEncounterCandidateState& c : held) out.push_back(FromState(c));
  }
  near_joined_ = s.near_joined;
  near_joined_known_ = s.near_joined_known;
  caught_up_frames_.clear();
}

}  // namespace anchormap
