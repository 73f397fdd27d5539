#include "common/solver/anchor_groups.h"

#include <gtest/gtest.h>

namespace anchormap {
namespace {

TEST(AnchorGroupsTest, OlderGroupSurvivesAndHandsBackTheAbsorbedPrior) {
  AnchorGroups groups;
  groups.CreateGroup(2, 100);  // B
  groups.Join(3, 2);           // C joins B
  groups.CreateGroup(4, 200);  // D
  groups.Join(5, 4);           // E joins D
  EXPECT_TRUE(groups.SameGroup(2, 3));
  EXPECT_FALSE(groups.SameGroup(3, 5));
  EXPECT_FALSE(groups.Contains(1));
  groups.Join(1, 3);  // A meets C
  EXPECT_EQ(groups.Root(1), 2);
  const AnchorGroups::Merge merge = groups.MergeGroups(5, 1);  // E meets A
  EXPECT_EQ(merge.surviving_root, 2);
  EXPECT_EQ(merge.absorbed_root, 4);
  EXPECT_EQ(merge.absorbed_prior_id, 200);
  for (TrajectoryId t : {1, 2, 3, 4, 5}) EXPECT_EQ(groups.Root(t), 2);
  EXPECT_EQ(groups.PriorOf(5), 100);
}

}  // namespace
}  // namespace anchormap
