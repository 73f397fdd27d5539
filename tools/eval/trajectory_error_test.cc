#include "tools/eval/trajectory_error.h"

#include <cmath>
#include <random>

#include <gtest/gtest.h>

namespace anchormap {
namespace {

TEST(AlignRigid2DTest, RecoversAKnownRigidTransformExactly) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> coordinate(-20.0, 20.0);
  for (const Pose2& T_ref_est : {Pose2(3.0, -1.0, 0.7), Pose2(-100.0, 40.0, 3.1),
                                 Pose2(0.5, 0.25, -2.5), Pose2(0.0, 0.0, 0.0)}) {
    std::vector<Eigen::Vector2d> estimate, reference;
    for (int i = 0; i < 50; ++i) {
      // One draw per statement: a call's argument order is unspecified (gcc's order kept).
      const double y = coordinate(rng);
      const double x = coordinate(rng);
      reference.emplace_back(x, y);
      estimate.push_back(T_ref_est.Inverse().TransformPoint(reference.back()));
    }
    const Pose2 found = AlignRigid2D(estimate, reference);
    EXPECT_NEAR(found.x(), T_ref_est.x(), 1e-10);
    EXPECT_NEAR(found.y(), T_ref_est.y(), 1e-10);
    EXPECT_NEAR(AngleDifference(found.theta(), T_ref_est.theta()), 0.0, 1e-12);
  }
}

TEST(AlignRigid2DTest, OnePointUsesTheFallbackRotation) {
  const Pose2 found = AlignRigid2D({{1.0, 0.0}}, {{5.0, 5.0}}, M_PI / 2);
  EXPECT_NEAR(found.theta(), M_PI / 2, 1e-15);
  EXPECT_NEAR(found.TransformPoint({1.0, 0.0}).x(), 5.0, 1e-12);
  EXPECT_NEAR(found.TransformPoint({1.0, 0.0}).y(), 5.0, 1e-12);
  EXPECT_EQ(AlignRigid2D({}, {}).vector(), Eigen::Vector3d::Zero());
}

TEST(MatchByTimeTest, NearestWithinTolerance) {
  const StampedTrajectory reference = {
      {100, Pose2(1, 0, 0)}, {200, Pose2(2, 0, 0)}, {300, Pose2(3, 0, 0)}};
  const StampedTrajectory estimate = {
      {90, Pose2()}, {150, Pose2()}, {260, Pose2()}, {420, Pose2()}, {10, Pose2()}};
  int64_t unmatched = 0;
  const std::vector<MatchedPose> matched = MatchByTime(estimate, reference, 50, &unmatched);
  ASSERT_EQ(matched.size(), 3u);
  EXPECT_EQ(unmatched, 2);                   // 420 and 10 are more than 50 us away
  EXPECT_EQ(matched[0].reference.x(), 1.0);  // 90 -> 100
  EXPECT_EQ(matched[1].reference.x(), 1.0);  // 150: a tie, the earlier one
  EXPECT_EQ(matched[2].reference.x(), 3.0);  // 260 -> 300
  EXPECT_EQ(matched[2].time_gap_us, 40);
}

// A square of side 2 and an estimate scaled by 1.1 about its centre, one heading off by 0.2,
// then moved by a rigid transform. By symmetry the best alignment undoes the rigid transform
// exactly (the scaling has no rotational or translational part), so by hand:
//   ATE translation: every corner 0.1 off in x and y: 0.1 * sqrt(2) each (rmse, mean, max).
//   ATE rotation: 0, 0, 0, 0.2: rmse sqrt(0.04 / 4) = 0.1, mean 0.05, max 0.2.
//   RPE translation: each side is 2.2 long instead of 2: 0.2, 0.2, 0.2.
//   RPE rotation: 0, 0, 0.2: mean 0.2 / 3.
TEST(ComputeTrajectoryErrorTest, PerturbedSquareHandComputed) {
  const Pose2 moved(3.0, -1.0, 0.7);
  const double corners[4][2] = {{0, 0}, {2, 0}, {2, 2}, {0, 2}};
  std::vector<MatchedPose> segment;
  for (int i = 0; i < 4; ++i) {
    MatchedPose m;
    m.utime = i;
    m.reference = Pose2(corners[i][0], corners[i][1], 0.0);
    const Pose2 scaled(1.0 + 1.1 * (corners[i][0] - 1.0), 1.0 + 1.1 * (corners[i][1] - 1.0),
                       i == 3 ? 0.2 : 0.0);
    m.estimate = Compose(moved, scaled);
    segment.push_back(m);
  }
  const TrajectoryError error = ComputeTrajectoryError({segment});
  EXPECT_EQ(error.matched, 4);
  const Pose2 expected_alignment = moved.Inverse();
  EXPECT_NEAR(error.T_reference_estimate.x(), expected_alignment.x(), 1e-12);
  EXPECT_NEAR(error.T_reference_estimate.y(), expected_alignment.y(), 1e-12);
  EXPECT_NEAR(error.T_reference_estimate.theta(), expected_alignment.theta(), 1e-12);
  EXPECT_NEAR(error.ate_translation_m.rmse, 0.1 * std::sqrt(2.0), 1e-12);
  EXPECT_NEAR(error.ate_translation_m.mean, 0.1 * std::sqrt(2.0), 1e-12);
  EXPECT_NEAR(error.ate_translation_m.max, 0.1 * std::sqrt(2.0), 1e-12);
  EXPECT_NEAR(error.ate_rotation_rad.rmse, 0.1, 1e-12);
  EXPECT_NEAR(error.ate_rotation_rad.mean, 0.05, 1e-12);
  EXPECT_NEAR(error.ate_rotation_rad.max, 0.2, 1e-12);
  EXPECT_EQ(error.rpe_translation_m.count, 3);
  EXPECT_NEAR(error.rpe_translation_m.mean, 0.2, 1e-12);
  EXPECT_NEAR(error.rpe_translation_m.max, 0.2, 1e-12);
  EXPECT_NEAR(error.rpe_rotation_rad.mean, 0.2 / 3, 1e-12);
  EXPECT_NEAR(error.rpe_rotation_rad.max, 0.2, 1e-12);
}

// Two robots, each exact on its own, but robot B's map sits 1 m too far in y. Alone each
// aligns perfectly; merged, one transform for both: the centroid difference splits the
// offset, (0, -0.5), and every pose is 0.5 m off (by hand, see the rotation argument in
// AlignRigid2D: the summed cross product of the centred pairs is 0 here).
TEST(ComputeTrajectoryErrorTest, OneAlignmentForAllRobotsExposesAnInconsistentMerge) {
  const auto pose = [](double x, double y) { return Pose2(x, y, 0.0); };
  const std::vector<MatchedPose> a = {{0, pose(0, 0), pose(0, 0), 0},
                                      {1, pose(1, 0), pose(1, 0), 0}};
  const std::vector<MatchedPose> b = {{0, pose(0, 3), pose(0, 2), 0},
                                      {1, pose(1, 3), pose(1, 2), 0}};
  EXPECT_NEAR(ComputeTrajectoryError({a}).ate_translation_m.rmse, 0.0, 1e-12);
  EXPECT_NEAR(ComputeTrajectoryError({b}).ate_translation_m.rmse, 0.0, 1e-12);
  const TrajectoryError merged = ComputeTrajectoryError({a, b});
  EXPECT_NEAR(merged.T_reference_estimate.x(), 0.0, 1e-12);
  EXPECT_NEAR(merged.T_reference_estimate.y(), -0.5, 1e-12);
  EXPECT_NEAR(merged.T_reference_estimate.theta(), 0.0, 1e-12);
  EXPECT_NEAR(merged.ate_translation_m.rmse, 0.5, 1e-12);
  EXPECT_NEAR(merged.ate_translation_m.min, 0.5, 1e-12);
  EXPECT_EQ(merged.rpe_translation_m.count, 2);  // no pair spans the two robots
  EXPECT_NEAR(merged.rpe_translation_m.max, 0.0, 1e-12);
}

}  // namespace
}  // namespace anchormap
