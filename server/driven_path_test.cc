#include "server/driven_path.h"

#include <gtest/gtest.h>

namespace anchormap {
namespace {

TEST(DrivenPathTest, SumsTheOdometryStepsAndFollowsTheRecordAsItGrows) {
  TrajectoryRecord record;
  record.solver_id = TrajectoryId(3);
  DrivenPath driven;
  EXPECT_EQ(driven.To(record, 0), 0.0);  // no keyframe yet
  // Steps of 3-4-5 m, then 1 m back (a path, not a displacement), turning on the way.
  record.odometry_poses = {Pose2(0, 0, 0), Pose2(3, 4, 1.0), Pose2(3, 5, 2.0)};
  EXPECT_DOUBLE_EQ(driven.To(record, 0), 0.0);
  EXPECT_DOUBLE_EQ(driven.To(record, 1), 5.0);
  EXPECT_DOUBLE_EQ(driven.To(record, 2), 6.0);
  record.odometry_poses.push_back(Pose2(3, 4, 0.0));
  EXPECT_DOUBLE_EQ(driven.To(record, 3), 7.0);
  // Clamped to the record's keyframes.
  EXPECT_DOUBLE_EQ(driven.To(record, 9), 7.0);
  EXPECT_DOUBLE_EQ(driven.To(record, -1), 0.0);
}

}  // namespace
}  // namespace anchormap
