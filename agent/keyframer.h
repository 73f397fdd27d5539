#pragma once
// Decides which scans become keyframes: when the robot has moved or turned more than a
// threshold since the last keyframe, or waited longer than a time limit (Cartographer's
// MotionFilter). A keyframe can also be forced, e.g. at an encounter.

#include <cstdint>
#include <optional>
#include <string>

#include "common/geometry/pose2.h"
#include "common/util/status.h"

namespace anchormap {

struct KeyframerOptions {
  // Translation since the last keyframe that makes a new one. Smaller: denser graph,
  // more solver work and bus traffic; larger: coarser map, longer odometry edges.
  double max_distance_m = 0.5;
  // Rotation since the last keyframe that makes a new one (0.35 rad = 20 degrees).
  double max_angle_rad = 0.35;
  // A keyframe at least this often even when standing still (keeps the server informed
  // that the robot is alive; 0 disables).
  double max_interval_s = 10.0;

  Status Validate() const {
    if (!(max_distance_m > 0)) return Status::Error("keyframer.max_distance_m must be > 0");
    if (!(max_angle_rad > 0)) return Status::Error("keyframer.max_angle_rad must be > 0");
    if (!(max_interval_s >= 0))
      return Status::Error("keyframer.max_interval_s must be >= 0 (0 = off)");
    return Status::Ok();
  }
};

class Keyframer {
 public:
  explicit Keyframer(const KeyframerOptions& options = {}) : options_(options) {}

  // True when a scan at `utime` with the robot at T_odom_body should become a keyframe:
  // the first scan, a forced one, or one past any threshold.
  bool ShouldMake(const Pose2& T_odom_body, int64_t utime) const;
  // Records that a keyframe was made (clears a pending force).
  void Accept(const Pose2& T_odom_body, int64_t utime);
  // Makes the next scan at or after `utime` a keyframe.
  void ForceAtOrAfter(int64_t utime);
  bool force_pending() const { return force_utime_.has_value(); }
  // True when a forced keyframe is due at `utime`.
  bool IsForcedAt(int64_t utime) const { return force_utime_ && utime >= *force_utime_; }

 private:
  KeyframerOptions options_;
  std::optional<Pose2> last_pose_;
  int64_t last_utime_ = 0;
  std::optional<int64_t> force_utime_;
};

}  // namespace anchormap
