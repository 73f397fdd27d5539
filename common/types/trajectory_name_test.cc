#include "common/types/trajectory_name.h"

#include <gtest/gtest.h>

namespace anchormap {
namespace {

TEST(TrajectoryNameTest, RobotAndIdTogetherNameATrajectory) {
  const TrajectoryName a{"R1", 5}, b{"R2", 5}, c{"R1", 6};
  EXPECT_NE(a, b);  // two robots may draw the same id
  EXPECT_NE(a, c);
  EXPECT_EQ(a, (TrajectoryName{"R1", 5}));
  EXPECT_LT(a, c);
  EXPECT_LT(a, b);
  EXPECT_EQ(a.ToString(), "R1/5");
}

}  // namespace
}  // namespace anchormap
