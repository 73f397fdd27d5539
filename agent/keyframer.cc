#include "agent/keyframer.h"

#include <algorithm>
#include <cmath>

namespace anchormap {

bool Keyframer::ShouldMake(const Pose2& T_odom_body, int64_t utime) const {
  if (!last_pose_) return true;
  if (IsForcedAt(utime)) return true;
  const Pose2 delta = Between(*last_pose_, T_odom_body);
  if (delta.translation().norm() >= options_.max_distance_m) return true;
  if (std::abs(delta.theta()) >= options_.max_angle_rad) return true;
  return options_.max_interval_s > 0 &&
         1e-6 * static_cast<double>(utime - last_utime_) >= options_.max_interval_s;
}

void Keyframer::Accept(const Pose2& T_odom_body, int64_t utime) {
  last_pose_ = T_odom_body;
  last_utime_ = utime;
  if (IsForcedAt(utime)) force_utime_.reset();
}

void Keyframer::ForceAtOrAfter(int64_t utime) {
  // Two encounters close together: the earlier time wins, the later keyframe follows from
  // the next force (the keyframe at the earlier time is also the nearest for both).
  force_utime_ = force_utime_ ? std::min(*force_utime_, utime) : utime;
}

}  // namespace anchormap
