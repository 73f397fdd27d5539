#pragma once
// The agent's odometry refinement (issue 11, item 2): each scan is matched against a local map
// of the last scans that entered it (LocalMapMatcher), around the pose odometry predicts. A good
// match replaces the odometry pose; otherwise the prediction stands and the fallback is counted.
// The CPU time of every scan is measured on the calling thread's clock, so that the status line
// can show what the robot pays for the refinement. Bounded memory: the local map's few scans.

#include <cstdint>
#include <functional>
#include <optional>

#include <Eigen/Core>

#include "common/geometry/pose2.h"
#include "common/scan_matching/local_map_matcher.h"
#include "common/types/laser_scan.h"
#include "common/util/status.h"

namespace anchormap {

struct ScanRefinementOptions {
  // Off: keyframe poses and constraints are odometry, as before issue 11.
  bool enabled = true;
  // Scans with fewer returns than this are not matched (too few points to constrain a pose,
  // and a handful can fit anywhere): odometry for them.
  int min_points = 30;
  LocalMapMatcherOptions local_map;

  Status Validate() const;
};

struct RefinedPose {
  Pose2 pose;  // T_local_body: matched when `matched`, else odometry from the last pose
  bool matched = false;
  // True when `pose` is known in the local map's frame: matched, or the scan started the map.
  bool in_map = false;
  // The scan entered the local map (its points now shape the map later scans match against).
  bool entered_map = false;
  // Of `pose` in the local map's frame when in_map: the matcher's (from its score
  // distribution), zero for the scan that started the map (it defines the frame).
  Eigen::Matrix3d covariance = Eigen::Matrix3d::Zero();
  // The match's score was flat along a direction (a corridor's axis): `pose` follows odometry
  // along it, and `covariance` has the match's reach along it (LocalMapUpdate::flat).
  bool flat = false;
  // Counts the local map's starts: two in_map poses of the same generation are known in one
  // continuous map, so their relative pose comes from the matcher too.
  int64_t map_generation = 0;
};

struct ScanRefinementStats {
  int64_t scans = 0;
  int64_t matched = 0;
  int64_t fallbacks = 0;  // odometry used: no match, a rejected match, or too few points
  int64_t too_few_points = 0;
  int64_t map_starts = 0;       // the first scan with points, then every reset
  int64_t flat = 0;             // matched, following odometry along a flat direction
  double cpu_s = 0.0;           // thread CPU time spent refining, total
  double max_scan_cpu_s = 0.0;  // the most one scan took
  double mean_scan_cpu_s() const { return scans > 0 ? cpu_s / static_cast<double>(scans) : 0.0; }
};

class ScanRefiner {
 public:
  // Options must be valid.
  explicit ScanRefiner(const ScanRefinementOptions& options);

  // `scan` with its mounting pose and max range set; `T_odom_body` the odometry pose at its
  // time. Scans come in time order. `needs_covariance` (the caller's keyframe rule): the
  // matcher's covariance is computed only for poses it accepts and for scans entering the local
  // map (the only ones whose covariance is used); `covariance` is the identity otherwise.
  RefinedPose Refine(const LaserScan& scan, const Pose2& T_odom_body,
                     const std::function<bool(const Pose2&)>& needs_covariance);

  const ScanRefinementStats& stats() const { return stats_; }
  bool enabled() const { return matcher_.has_value(); }

 private:
  ScanRefinementOptions options_;
  std::optional<LocalMapMatcher> matcher_;
  ScanRefinementStats stats_;
  int64_t map_generation_ = 0;
};

// The covariance of T_a_b = Between(T_l_a, T_l_b) when both poses were matched against one
// local map with covariances cov_a and cov_b (independent errors against the map; the map's
// own error is common to both and cancels in the relative pose).
Eigen::Matrix3d RelativePoseCovariance(const Pose2& T_l_a, const Eigen::Matrix3d& cov_a,
                                       const Pose2& T_l_b, const Eigen::Matrix3d& cov_b);

}  // namespace anchormap
