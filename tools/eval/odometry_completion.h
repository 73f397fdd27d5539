#pragma once
// Poses of an estimate between its keyframes, from the raw odometry: the pose at time t is the
// keyframe k nearest in time composed with the odometry motion from k's time to t,
//   X(t) = X(k) (+) Between(odom(t_k), odom(t)),
// odometry interpolated linearly at both times. This is how a keyframe-based mapper places the
// scans it did not keep. The relations metric needs it: the benchmark's relations join
// particular scans, and with keyframes every 0.5 m only a few of them are keyframes.
// An extension of the benchmark's "nearest estimated pose" rule; anchormap-eval applies it only
// when given the raw log (--odometry) and says so in its output.

#include <cstdint>
#include <optional>
#include <vector>

#include "common/types/stamped_pose2.h"

namespace anchormap {

// Odometry pose at `utime` interpolated between the two samples around it (x, y linearly,
// theta along the shorter arc); nullopt outside the samples' span or when the two samples are
// farther apart than `max_sample_gap_us`. `odometry` sorted by time.
std::optional<Pose2> InterpolateOdometry(const StampedTrajectory& odometry, int64_t utime,
                                         int64_t max_sample_gap_us);

// The estimate at each of `query_utimes` (any order) that lies within
// [first keyframe - max_extrapolation_us, last keyframe + max_extrapolation_us] and where the
// odometry is available; returned sorted by time. `keyframes` and `odometry` sorted by time.
StampedTrajectory CompleteWithOdometry(const StampedTrajectory& keyframes,
                                       const StampedTrajectory& odometry,
                                       const std::vector<int64_t>& query_utimes,
                                       int64_t max_extrapolation_us, int64_t max_sample_gap_us);

}  // namespace anchormap
