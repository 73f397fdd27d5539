#include "agent/scan_refiner.h"

#include <time.h>

#include <algorithm>

#include "common/scan_matching/point_cloud.h"

namespace anchormap {
namespace {

// CPU time of the calling thread (not wall time: the robot's other processes and a slow bus
// must not count), seconds.
double ThreadCpuSeconds() {
  timespec now{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &now);
  return static_cast<double>(now.tv_sec) + 1e-9 * static_cast<double>(now.tv_nsec);
}

}  // namespace

Status ScanRefinementOptions::Validate() const {
  if (min_points < 1) return Status::Error("scan_matching.min_points must be >= 1");
  if (Status valid = local_map.Validate(); !valid.ok()) {
    return Status::Error("scan_matching: " + valid.message());
  }
  return Status::Ok();
}

ScanRefiner::ScanRefiner(const ScanRefinementOptions& options) : options_(options) {
  if (options.enabled) matcher_.emplace(options.local_map);
}

RefinedPose ScanRefiner::Refine(const LaserScan& scan, const Pose2& T_odom_body,
                                const std::function<bool(const Pose2&)>& needs_covariance) {
  RefinedPose refined;
  if (!matcher_) {
    refined.pose = T_odom_body;
    return refined;
  }
  const double start = ThreadCpuSeconds();
  ++stats_.scans;
  PointCloud points = ScanToPointCloud(scan);
  if (static_cast<int>(points.size()) < options_.min_points) {
    // The matcher still follows the odometry (its prediction), with nothing to match.
    points.clear();
    ++stats_.too_few_points;
  }
  const LocalMapUpdate update = matcher_->AddScan(points, T_odom_body, needs_covariance);
  refined.pose = update.pose;
  refined.matched = update.matched;
  refined.entered_map = update.keyframe;
  if (update.matched) {
    refined.in_map = true;
    refined.covariance = update.match->covariance;
    refined.flat = update.flat.has_value();
    if (refined.flat) ++stats_.flat;
    ++stats_.matched;
  } else {
    ++stats_.fallbacks;
    if (update.keyframe) {
      // Unmatched yet entered the map: the map (re)started here, in this scan's frame.
      refined.in_map = true;
      ++map_generation_;
      ++stats_.map_starts;
    }
  }
  refined.map_generation = map_generation_;
  const double spent = ThreadCpuSeconds() - start;
  stats_.cpu_s += spent;
  stats_.max_scan_cpu_s = std::max(stats_.max_scan_cpu_s, spent);
  return refined;
}

Eigen::Matrix3d RelativePoseCovariance(const Pose2& T_l_a, const Eigen::Matrix3d& cov_a,
                                       const Pose2& T_l_b, const Eigen::Matrix3d& cov_b) {
  Eigen::Matrix3d J_a, J_b;
  Between(T_l_a, T_l_b, &J_a, &J_b);
  const Eigen::Matrix3d covariance = J_a * cov_a * J_a.transpose() + J_b * cov_b * J_b.transpose();
  return 0.5 * (covariance + covariance.transpose());
}

}  // namespace anchormap
