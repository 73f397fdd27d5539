#include "tools/eval/trajectory_error.h"

#include <algorithm>
#include <cmath>

namespace anchormap {

Pose2 AlignRigid2D(const std::vector<Eigen::Vector2d>& estimate,
                   const std::vector<Eigen::Vector2d>& reference, double fallback_rotation_rad) {
  const size_t n = std::min(estimate.size(), reference.size());
  if (n == 0) return Pose2();
  Eigen::Vector2d estimate_mean = Eigen::Vector2d::Zero(), reference_mean = Eigen::Vector2d::Zero();
  for (size_t i = 0; i < n; ++i) {
    estimate_mean += estimate[i];
    reference_mean += reference[i];
  }
  estimate_mean /= static_cast<double>(n);
  reference_mean /= static_cast<double>(n);
  // In 2D the optimal rotation angle is atan2 of the summed cross and dot products of the
  // centred pairs (the 2x2 case of the SVD solution).
  double dot = 0.0, cross = 0.0, spread = 0.0;
  for (size_t i = 0; i < n; ++i) {
    const Eigen::Vector2d e = estimate[i] - estimate_mean;
    const Eigen::Vector2d r = reference[i] - reference_mean;
    dot += e.dot(r);
    cross += e.x() * r.y() - e.y() * r.x();
    spread += e.squaredNorm();
  }
  const double theta = spread > 1e-18 && (dot != 0.0 || cross != 0.0) ? std::atan2(cross, dot)
                                                                      : fallback_rotation_rad;
  const Pose2 rotation(0.0, 0.0, theta);
  const Eigen::Vector2d t = reference_mean - rotation.rotation() * estimate_mean;
  return Pose2(t.x(), t.y(), theta);
}

std::vector<MatchedPose> MatchByTime(const StampedTrajectory& estimate,
                                     const StampedTrajectory& reference, int64_t max_time_gap_us,
                                     int64_t* unmatched) {
  std::vector<MatchedPose> matched;
  *unmatched = 0;
  for (const StampedPose2& pose : estimate) {
    const auto it = std::lower_bound(reference.begin(), reference.end(), pose.utime,
                                     [](const StampedPose2& r, int64_t t) { return r.utime < t; });
    const StampedPose2* best = nullptr;
    if (it != reference.end()) best = &*it;
    if (it != reference.begin()) {
      const StampedPose2* before = &*(it - 1);
      if (!best || pose.utime - before->utime <= best->utime - pose.utime) best = before;
    }
    if (!best || std::abs(best->utime - pose.utime) > max_time_gap_us) {
      ++*unmatched;
      continue;
    }
    matched.push_back({pose.utime, pose.pose, best->pose, std::abs(best->utime - pose.utime)});
  }
  return matched;
}

TrajectoryError ComputeTrajectoryError(const std::vector<std::vector<MatchedPose>>& segments) {
  TrajectoryError result;
  std::vector<Eigen::Vector2d> estimate_points, reference_points;
  double sin_sum = 0.0, cos_sum = 0.0, gap_sum_us = 0.0;
  for (const auto& segment : segments) {
    for (const MatchedPose& m : segment) {
      estimate_points.push_back(m.estimate.translation());
      reference_points.push_back(m.reference.translation());
      const double heading_difference = AngleDifference(m.reference.theta(), m.estimate.theta());
      sin_sum += std::sin(heading_difference);
      cos_sum += std::cos(heading_difference);
      gap_sum_us += static_cast<double>(m.time_gap_us);
    }
  }
  result.matched = static_cast<int64_t>(estimate_points.size());
  if (result.matched == 0) return result;
  result.mean_time_gap_s = 1e-6 * gap_sum_us / static_cast<double>(result.matched);
  result.T_reference_estimate =
      AlignRigid2D(estimate_points, reference_points, std::atan2(sin_sum, cos_sum));

  std::vector<double> ate_t, ate_r, rpe_t, rpe_r;
  for (const auto& segment : segments) {
    for (size_t i = 0; i < segment.size(); ++i) {
      const Pose2 aligned = Compose(result.T_reference_estimate, segment[i].estimate);
      ate_t.push_back((aligned.translation() - segment[i].reference.translation()).norm());
      ate_r.push_back(std::abs(AngleDifference(aligned.theta(), segment[i].reference.theta())));
      if (i == 0) continue;
      const Pose2 estimated_step = Between(segment[i - 1].estimate, segment[i].estimate);
      const Pose2 reference_step = Between(segment[i - 1].reference, segment[i].reference);
      rpe_t.push_back((estimated_step.translation() - reference_step.translation()).norm());
      rpe_r.push_back(std::abs(AngleDifference(estimated_step.theta(), reference_step.theta())));
    }
  }
  result.ate_translation_m = ComputeErrorStats(std::move(ate_t));
  result.ate_rotation_rad = ComputeErrorStats(std::move(ate_r));
  result.rpe_translation_m = ComputeErrorStats(std::move(rpe_t));
  result.rpe_rotation_rad = ComputeErrorStats(std::move(rpe_r));
  return result;
}

}  // namespace anchormap
