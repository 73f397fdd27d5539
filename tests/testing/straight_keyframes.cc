#include "tests/testing/straight_keyframes.h"

#include <Eigen/Core>

namespace anchormap::testing {

Keyframe StraightKeyframe(const std::string& robot, int64_t trajectory_id, int32_t seq,
                          int num_rays, int64_t first_utime) {
  Keyframe k;
  k.robot = robot;
  k.trajectory_id = trajectory_id;
  k.seq = seq;
  k.utime = first_utime + 1'000'000 * static_cast<int64_t>(seq);
  k.T_local_pose = Pose2(seq, 0.0, 0.0);
  if (seq > 0) {
    k.T_previous_this = Pose2(1.0, 0.0, 0.0);
    k.T_previous_this_covariance = Eigen::Vector3d(1e-4, 1e-4, 1e-6).asDiagonal();
  }
  k.scan.rad0 = 0.0f;
  k.scan.radstep = 0.01f;
  k.scan.max_range = 10.0f;
  k.scan.ranges.assign(static_cast<size_t>(num_rays), 2.0f);
  return k;
}

}  // namespace anchormap::testing
