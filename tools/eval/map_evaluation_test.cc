#include "tools/eval/map_evaluation.h"

#include <cmath>

#include <gtest/gtest.h>

namespace anchormap {
namespace {

// Reference: R1 drives along y = 0, R2 along y = 2, poses every 1 s (utime 1e6 * i).
StampedTrajectory Line(double y, int count) {
  StampedTrajectory poses;
  for (int i = 0; i < count; ++i) poses.push_back({1000000LL * i, Pose2(i, y, 0.0)});
  return poses;
}

EstimatedTrajectory Estimated(const std::string& robot, int64_t id, bool anchored, int group,
                              const StampedTrajectory& truth, const Pose2& T_est_ref) {
  EstimatedTrajectory t;
  t.robot = robot;
  t.trajectory_id = id;
  t.anchored = anchored;
  t.group = group;
  for (const StampedPose2& p : truth) t.poses.push_back({p.utime, Compose(T_est_ref, p.pose)});
  return t;
}

TEST(EvaluateAgainstReferencesTest, PerRobotAndMergedRows) {
  ReferenceSet references;
  references.by_robot["R1"] = Line(0.0, 5);
  references.by_robot["R2"] = Line(2.0, 5);
  references.source_by_robot["R1"] = "R1_GROUND_TRUTH";
  references.source_by_robot["R2"] = "R2_GROUND_TRUTH";
  MapEstimate estimate;
  estimate.update = 9;
  estimate.num_groups = 1;
  const Pose2 global(10.0, -3.0, 0.4);  // one frame for the merged map
  estimate.trajectories = {Estimated("R1", 1, true, 0, Line(0.0, 5), global),
                           Estimated("R2", 2, true, 0, Line(2.0, 5), global),
                           Estimated("R3", 3, false, -1, Line(0.0, 3), Pose2())};
  // R2's map is 1 m off (along the reference's y): fine on its own, not merged consistently.
  estimate.trajectories[1] = Estimated("R2", 2, true, 0, Line(3.0, 5), global);
  // A keyframe 0.3 s away from every reference pose is not matched.
  estimate.trajectories[0].poses.push_back({4300000, Pose2()});

  const AteReport report = EvaluateAgainstReferences(estimate, references, 0.05);
  ASSERT_EQ(report.trajectories.size(), 3u);
  const TrajectoryReport& r1 = report.trajectories[0];
  EXPECT_EQ(r1.label, "R1");
  EXPECT_EQ(r1.poses, 6);
  EXPECT_EQ(r1.error.matched, 5);
  EXPECT_EQ(r1.unmatched, 1);
  EXPECT_NEAR(r1.error.ate_translation_m.max, 0.0, 1e-9);
  EXPECT_NEAR(report.trajectories[1].error.ate_translation_m.max, 0.0, 1e-9);
  EXPECT_EQ(report.trajectories[2].reference, "");  // no R3 reference
  EXPECT_EQ(report.trajectories[2].error.matched, 0);
  ASSERT_TRUE(report.has_merged);
  EXPECT_EQ(report.merged.members, (std::vector<std::string>{"R1", "R2"}));
  EXPECT_EQ(report.merged.error.matched, 10);
  // One alignment for both: as in the two-robot hand computation of trajectory_error_test,
  // every pose ends 0.5 m off.
  EXPECT_NEAR(report.merged.error.ate_translation_m.rmse, 0.5, 1e-9);
  EXPECT_NEAR(report.merged.error.ate_translation_m.min, 0.5, 1e-9);
}

TEST(BuildRelationsEstimateTest, MergesInTimeOrderWithFrames) {
  MapEstimate estimate;
  estimate.num_groups = 1;
  estimate.trajectories = {Estimated("R1", 1, true, 0, Line(0.0, 2), Pose2()),
                           Estimated("R2", 2, false, -1, Line(2.0, 3), Pose2())};
  RelationsEstimate all;
  ASSERT_TRUE(BuildRelationsEstimate(estimate, "", &all).ok());
  ASSERT_EQ(all.poses.size(), 5u);
  EXPECT_EQ(all.frame_ids, (std::vector<int>{0, 2, 0, 2, 2}));  // R2 unanchored: frame 1 + 1
  RelationsEstimate r2;
  ASSERT_TRUE(BuildRelationsEstimate(estimate, "R2", &r2).ok());
  EXPECT_EQ(r2.poses.size(), 3u);
  EXPECT_EQ(BuildRelationsEstimate(estimate, "R9", &r2).message(),
            "no poses of robot R9 in the estimate (trajectories of: R1 R2)");
}

}  // namespace
}  // namespace anchormap
