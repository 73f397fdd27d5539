#pragma once
// Absolute trajectory error (ATE) and relative pose error (RPE) of an estimated trajectory
// against a reference (Sturm et al., "A benchmark for the evaluation of RGB-D SLAM systems",
// IROS 2012, in 2D): estimate and reference are matched by time, the estimate is aligned to
// the reference by the rigid transform minimising the squared position differences (closed
// form, Horn 1987 / Umeyama 1991 without scale), and the errors are taken after alignment.
// Several segments (robots) can share one alignment: the merged map's test, since a map that
// is merged consistently needs only one transform for all its robots.

#include <cstdint>
#include <vector>

#include <Eigen/Core>

#include "common/types/stamped_pose2.h"
#include "tools/eval/error_stats.h"

namespace anchormap {

// The rigid transform T_ref_est minimising sum_i |ref_i - T_ref_est * est_i|^2 over the
// pairs (est_i, ref_i). Exact for point sets related by a rigid transform. With fewer than two
// distinct estimate points the rotation is undetermined: it is then taken from
// `fallback_rotation_rad` (e.g. the mean heading difference). Returns the identity when empty.
Pose2 AlignRigid2D(const std::vector<Eigen::Vector2d>& estimate,
                   const std::vector<Eigen::Vector2d>& reference,
                   double fallback_rotation_rad = 0.0);

// One estimated pose and the reference pose matched to it.
struct MatchedPose {
  int64_t utime = 0;  // the estimate's time
  Pose2 estimate;
  Pose2 reference;
  int64_t time_gap_us = 0;  // |reference time - estimate time|
};

// For each estimated pose, the reference pose nearest in time if at most `max_time_gap_us`
// away (reference sorted by time). *unmatched counts the others. O(n log m).
std::vector<MatchedPose> MatchByTime(const StampedTrajectory& estimate,
                                     const StampedTrajectory& reference, int64_t max_time_gap_us,
                                     int64_t* unmatched);

struct TrajectoryError {
  int64_t matched = 0;
  Pose2 T_reference_estimate;    // the alignment applied to the estimate
  ErrorStats ate_translation_m;  // |ref - aligned estimate| per matched pose
  ErrorStats ate_rotation_rad;   // |wrapped heading difference| per matched pose
  ErrorStats rpe_translation_m;  // per pair of consecutive matched poses of one segment
  ErrorStats rpe_rotation_rad;
  double mean_time_gap_s = 0.0;
};

// Errors of the segments aligned together (one transform). RPE pairs never span two
// segments; RPE does not depend on the alignment.
TrajectoryError ComputeTrajectoryError(const std::vector<std::vector<MatchedPose>>& segments);

}  // namespace anchormap
