#include "server/loop_closures.h"

#include <algorithm>
#include <cmath>
#include <future>
#include <limits>
#include <memory>
#include <utility>
#include <vector>

#include <Eigen/Eigenvalues>

#include "common/scan_matching/point_cloud.h"
#include "server/keyframe_submap.h"
#include "server/relative_pose.h"

namespace anchormap {

Status LoopClosureOptions::Validate() const {
  if (min_index_gap < 1) return Status::Error("loop.min_index_gap must be >= 1");
  if (!(max_distance_m > 0)) return Status::Error("loop.max_distance_m must be > 0");
  if (!(candidate_chi2 > 0) || !(gate_chi2 > 0))
    return Status::Error("loop chi2 gates must be > 0");
  if (max_candidates < 0) return Status::Error("loop.max_candidates must be >= 0");
  if (cooldown_keyframes < 0) return Status::Error("loop.cooldown_keyframes must be >= 0");
  if (submap_half_width < 0) return Status::Error("loop.submap_half_width must be >= 0");
  if (!(max_range_m > 0)) return Status::Error("loop.max_range_m must be > 0");
  if (!(min_window_m > 0) || !(max_window_m >= min_window_m))
    return Status::Error("loop window: 0 < min_window_m <= max_window_m");
  if (!(min_window_rad > 0) || !(max_window_rad >= min_window_rad))
    return Status::Error("loop window: 0 < min_window_rad <= max_window_rad");
  if (!(floor_sigma_m >= 0) || !(floor_sigma_rad >= 0))
    return Status::Error("loop covariance floors must be >= 0");
  if (max_waiting < 1) return Status::Error("loop.max_waiting must be >= 1");
  if (Status s = reference.Validate(); !s.ok()) return s;
  return match.Validate();
}

namespace {

// Squared Mahalanobis distance of the offset t from the disc of radius r around 0.
double DistanceFromDisc2(const Eigen::Vector2d& t, const Eigen::Matrix2d& covariance, double r) {
  const double norm = t.norm();
  if (norm <= r) return 0.0;
  const Eigen::Vector2d outside = t - t * (r / norm);
  const Eigen::LDLT<Eigen::Matrix2d> ldlt(covariance);
  if (ldlt.info() != Eigen::Success || ldlt.vectorD().minCoeff() <= 0.0) return 1e30;
  return outside.dot(ldlt.solve(outside));
}

double LargestSigma(const Eigen::Matrix2d& covariance) {
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d> eigen(covariance);
  return std::sqrt(std::max(0.0, eigen.eigenvalues().maxCoeff()));
}

}  // namespace

void LoopClosures::OnKeyframeAdded(PoseKey key, const GraphView& /*graph*/,
                                   EncounterSourceOutput* /*out*/) {
  waiting_.push_back(key);
  while (static_cast<int>(waiting_.size()) > options_.max_waiting) waiting_.pop_front();
}

void LoopClosures::Poll(int64_t now_utime, const GraphView& graph, EncounterSourceOutput* out) {
  now_utime_ = std::max(now_utime_, now_utime);
  Examine(graph, out);
}

void LoopClosures::Flush(const GraphView& graph, EncounterSourceOutput* out) {
  Examine(graph, out);
  UseMatches(now_utime_, /*all=*/true, out);
}

void LoopClosures::Examine(const GraphView& graph, EncounterSourceOutput* out) {
  if (graph.covariances == nullptr) return;
  // In arrival order; a keyframe not solved yet (it arrived in this very call) waits.
  std::deque<PoseKey> still_waiting;
  for (const PoseKey key : waiting_) {
    if (!graph.covariances->HasCovariance(key)) {
      still_waiting.push_back(key);
      continue;
    }
    ExamineKeyframe(key, graph);
    UseMatches(now_utime_, /*all=*/false, out);
  }
  waiting_ = std::move(still_waiting);
  UseMatches(now_utime_, /*all=*/false, out);
}

void LoopClosures::UseMatches(int64_t now_utime, bool all, EncounterSourceOutput* out) {
  while (!matches_.empty() && (all || matches_.front().due_utime <= now_utime)) {
    const PendingMatch pending = std::move(matches_.front());
    matches_.pop_front();
    const std::optional<MatchResult> match = pending.result.get();
    if (!match) {
      ++stats_.no_match;
      continue;
    }
    if (match->score < options_.min_score || match->overlap < options_.min_overlap) {
      ++stats_.weak_match;
      continue;
    }
    const Eigen::Matrix3d covariance =
        WithCovarianceFloor(match->covariance, options_.floor_sigma_m, options_.floor_sigma_rad);
    if (Mahalanobis2(pending.predicted.T_a_b, match->pose,
                     pending.predicted.covariance + covariance) > options_.gate_chi2) {
      ++stats_.gate_rejected;
      continue;
    }
    ++stats_.accepted;
    EncounterConstraint constraint;
    constraint.a = pending.candidate;
    constraint.b = pending.key;
    constraint.measured_T_a_b = match->pose;
    constraint.covariance = covariance;
    constraint.utime = pending.key_utime;
    constraint.source = name();
    constraint.kind = ConstraintKind::kLoopClosure;
    out->constraints.push_back(constraint);
    quiet_until_[pending.key.trajectory] = pending.key.index + 1 + options_.cooldown_keyframes;
  }
}

void LoopClosures::ExamineKeyframe(PoseKey key, const GraphView& graph) {
  Smoother* smoother = graph.covariances;
  const TrajectoryRecord* record = graph.table.FindBySolverId(key.trajectory);
  if (record == nullptr || key.index >= record->num_keyframes()) return;
  if (record->scans[static_cast<size_t>(key.index)].ranges.empty()) return;
  if (options_.max_candidates == 0) return;
  if (const auto quiet = quiet_until_.find(key.trajectory);
      quiet != quiet_until_.end() && key.index < quiet->second) {
    return;
  }
  const int last_candidate = key.index - options_.min_index_gap;
  if (last_candidate < 0) return;

  // Cheap prefilter on the estimates: within the disc plus 3 sigma of the keyframe's own
  // uncertainty (twice: the candidate's is usually smaller, the gauge being at index 0).
  const Pose2 T_local_key = smoother->FramePose(key);
  const double slack = 6.0 * LargestSigma(smoother->MarginalCovariance(key).topLeftCorner<2, 2>());
  std::vector<std::pair<double, int>> near;
  for (int j = 0; j <= last_candidate; ++j) {
    const PoseKey candidate{key.trajectory, j};
    if (!smoother->HasPose(candidate)) continue;
    const double distance =
        (smoother->FramePose(candidate).translation() - T_local_key.translation()).norm();
    if (distance <= options_.max_distance_m + slack) near.emplace_back(distance, j);
  }
  std::sort(near.begin(), near.end());

  // The joint-covariance gate, nearest first; candidates apart by more than a submap.
  std::vector<std::pair<int, PredictedRelativePose>> chosen;
  const size_t max_examined = static_cast<size_t>(4 * options_.max_candidates);
  for (size_t n = 0; n < near.size() && n < max_examined; ++n) {
    const int j = near[n].second;
    const bool overlaps_chosen = std::any_of(chosen.begin(), chosen.end(), [&](const auto& c) {
      return std::abs(c.first - j) <= options_.submap_half_width;
    });
    if (overlaps_chosen) continue;
    const std::optional<PredictedRelativePose> predicted =
        PredictRelativePose(smoother, PoseKey{key.trajectory, j}, key);
    if (!predicted) continue;
    if (DistanceFromDisc2(predicted->T_a_b.translation(),
                          predicted->covariance.topLeftCorner<2, 2>(),
                          options_.max_distance_m) > options_.candidate_chi2) {
      continue;
    }
    chosen.emplace_back(j, *predicted);
    if (static_cast<int>(chosen.size()) >= options_.max_candidates) break;
  }
  if (chosen.empty()) return;

  // The jobs own what they read: the query's points, the submap (immutable once built).
  const auto query =
      std::make_shared<const PointCloud>(KeyframePoints(*record, key.index, options_.max_range_m));
  for (const auto& [j, predicted] : chosen) {
    ++stats_.candidates;
    const PoseKey candidate{key.trajectory, j};
    std::shared_ptr<const ScanReference> submap =
        BuildKeyframeSubmap(*record, graph.smoother, candidate, options_.submap_half_width,
                            options_.max_range_m, options_.reference);
    if (!submap) {
      ++stats_.no_match;
      continue;
    }
    LocalMatchOptions window;
    window.match = options_.match;
    const double sigma_xy = LargestSigma(predicted.covariance.topLeftCorner<2, 2>());
    const double sigma_theta = std::sqrt(std::max(0.0, predicted.covariance(2, 2)));
    window.linear_window_m =
        std::clamp(3.0 * sigma_xy, options_.min_window_m, options_.max_window_m);
    window.angular_window_rad =
        std::clamp(3.0 * sigma_theta, options_.min_window_rad, options_.max_window_rad);
    PendingMatch pending;
    pending.candidate = candidate;
    pending.key = key;
    pending.key_utime = record->utimes[static_cast<size_t>(key.index)];
    pending.due_utime =
        pool_ ? schedule_.DueUtime(pending.key_utime) : std::numeric_limits<int64_t>::min();
    pending.predicted = predicted;
    const Pose2 guess = predicted.T_a_b;
    auto job = [submap, query, guess, window] {
      return MatchLocal(*submap, *query, guess, window);
    };
    pending.result = RunMatch(pool_, std::move(job));
    matches_.push_back(std::move(pending));
  }
}

}  // namespace anchormap
