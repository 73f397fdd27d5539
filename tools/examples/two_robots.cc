// Two robots, each mapping in its own frame, joined by anchor nodes (docs/METHOD.md
// section 4). Robot 1 starts at the world origin; robot 2 starts at (4, 3) facing north,
// which neither robot knows. Both drive 1 m per step.
//   1. Each robot's odometry alone: two pose graphs in two local frames, no anchors.
//   2. A first encounter (robot 1 sees robot 2): only the anchors move; every pose keeps
//      its local estimate, and robot 2's global poses land where they are in the world.
//   3. A second encounter that disagrees with the first by 0.2 m: the least-squares
//      answer splits the difference between the two, and equals a batch solve.
// Prints each step; exits non-zero if any of these does not hold. Runs in ctest.

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <string>

#include <Eigen/Core>

#include "common/geometry/pose2.h"
#include "common/solver/smoother.h"

namespace {

using anchormap::Pose2;
using anchormap::TrajectoryId;

int failures = 0;

void Check(bool ok, const std::string& what) {
  std::printf("  [%s] %s\n", ok ? "ok" : "FAILED", what.c_str());
  if (!ok) ++failures;
}

void Print(const char* name, const Pose2& p) {
  std::printf("  %-28s x %7.3f  y %7.3f  theta %7.3f\n", name, p.x(), p.y(), p.theta());
}

}  // namespace

int main() {
  const Eigen::Matrix3d odometry_sigma2 = Eigen::Vector3d(1e-4, 1e-4, 1e-6).asDiagonal();
  const Eigen::Matrix3d encounter_sigma2 = Eigen::Vector3d(1e-2, 1e-2, 1e-3).asDiagonal();
  const Pose2 step(1.0, 0.0, 0.0);
  const Pose2 world_T_robot2_start(4.0, 3.0, M_PI / 2);  // unknown to the robots
  const TrajectoryId robot_1(1), robot_2(2);

  anchormap::Smoother smoother;  // relative formulation, iSAM defaults
  for (const TrajectoryId robot : {robot_1, robot_2}) {
    for (int i = 0; i <= 4; ++i) {
      const Pose2 local(static_cast<double>(i), 0.0, 0.0);  // odometry: straight ahead
      if (!smoother.AddPose({robot, i}, local).ok()) return 1;
      if (i > 0 && !smoother.AddBetween({robot, i - 1}, {robot, i}, step, odometry_sigma2).ok())
        return 1;
    }
  }
  if (!smoother.Update().status.ok()) return 1;
  std::printf("1. odometry only\n");
  Check(!smoother.IsAnchored(robot_1) && !smoother.IsAnchored(robot_2),
        "no anchors before an encounter");
  const Pose2 robot2_local_3 = smoother.FramePose({robot_2, 3});

  // Robot 1 at its pose 2 (world (2, 0)) sees robot 2 at its pose 1 (world (4, 4), north).
  const Pose2 world_T_r1_2(2.0, 0.0, 0.0);
  const Pose2 world_T_r2_1 = anchormap::Compose(world_T_robot2_start, step);
  const Pose2 seen_1 = anchormap::Between(world_T_r1_2, world_T_r2_1);
  if (!smoother.AddEncounter({robot_1, 2}, {robot_2, 1}, seen_1, encounter_sigma2).ok()) return 1;
  if (!smoother.Update().status.ok()) return 1;
  std::printf("2. first encounter R1[2] -> R2[1]\n");
  Print("anchor of robot 1", *smoother.Anchor(robot_1));
  Print("anchor of robot 2", *smoother.Anchor(robot_2));
  Check(anchormap::PoseError(smoother.FramePose({robot_2, 3}), robot2_local_3).norm() < 1e-12,
        "robot 2's local poses did not move");
  Check(anchormap::PoseError(*smoother.Anchor(robot_2), world_T_robot2_start).norm() < 1e-9,
        "robot 2's anchor is its start pose in the world (robot 1's frame)");
  Print("robot 2 pose 3, global", smoother.GlobalPose({robot_2, 3}));

  // Robot 1 at pose 4 sees robot 2 at pose 3, but this measurement is 0.2 m off along
  // robot 1's heading: the two encounters disagree.
  const Pose2 world_T_r1_4(4.0, 0.0, 0.0);
  const Pose2 world_T_r2_3 = anchormap::Compose(world_T_robot2_start, Pose2(3.0, 0.0, 0.0));
  const Pose2 truth_2 = anchormap::Between(world_T_r1_4, world_T_r2_3);
  const Pose2 seen_2(truth_2.x() + 0.2, truth_2.y(), truth_2.theta());
  if (!smoother.AddEncounter({robot_1, 4}, {robot_2, 3}, seen_2, encounter_sigma2).ok()) return 1;
  if (!smoother.Update().status.ok()) return 1;
  const anchormap::UpdateResult converged = smoother.BatchOptimize();
  if (!converged.status.ok()) return 1;
  std::printf("3. second encounter R1[4] -> R2[3], 0.2 m off\n");
  Print("anchor of robot 2", *smoother.Anchor(robot_2));
  const double residual_1 =
      anchormap::Between(smoother.GlobalPose({robot_1, 2}), smoother.GlobalPose({robot_2, 1})).x() -
      seen_1.x();
  const double residual_2 =
      anchormap::Between(smoother.GlobalPose({robot_1, 4}), smoother.GlobalPose({robot_2, 3})).x() -
      seen_2.x();
  std::printf("  along-track residuals: first %+.4f m, second %+.4f m; chi2 %.4f\n", residual_1,
              residual_2, smoother.Chi2());
  // Equal covariances and stiff odometry: the least-squares answer splits the 0.2 m evenly
  // between the two encounters; a small turn of robot 2's anchor (the two sightings have
  // different lever arms) absorbs a little of it, so each keeps just under 0.1 m.
  Check(std::abs(residual_1 + residual_2) < 1e-6 && residual_1 > 0.05 && residual_1 < 0.1,
        "the disagreement is split evenly between the two encounters");
  // The same factors solved in one batch give the same estimate.
  anchormap::Smoother batch;
  for (const TrajectoryId robot : {robot_1, robot_2}) {
    for (int i = 0; i <= 4; ++i) {
      if (!batch.AddPose({robot, i}, Pose2(static_cast<double>(i), 0.0, 0.0)).ok()) return 1;
      if (i > 0 && !batch.AddBetween({robot, i - 1}, {robot, i}, step, odometry_sigma2).ok())
        return 1;
    }
  }
  if (!batch.AddEncounter({robot_1, 2}, {robot_2, 1}, seen_1, encounter_sigma2).ok()) return 1;
  if (!batch.AddEncounter({robot_1, 4}, {robot_2, 3}, seen_2, encounter_sigma2).ok()) return 1;
  if (!batch.BatchOptimize().status.ok()) return 1;
  double largest = 0.0;
  for (const TrajectoryId robot : {robot_1, robot_2}) {
    for (int i = 0; i <= 4; ++i) {
      largest = std::max(largest, anchormap::PoseError(smoother.GlobalPose({robot, i}),
                                                       batch.GlobalPose({robot, i}))
                                      .cwiseAbs()
                                      .maxCoeff());
    }
  }
  Check(largest < 1e-6, "incremental equals the batch least-squares solution");
  std::printf(failures == 0 ? "all checks passed\n" : "%d check(s) failed\n", failures);
  return failures == 0 ? 0 : 1;
}
