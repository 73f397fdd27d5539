#include "common/solver/anchor_groups.h"

#include <gtest/gtest.h>

namespace anchormap {
namespace {

TEST(AnchorGroupsTest, OlderGroupSurvivesAndHandsBackTheAbsorbedPrior) {
  const TrajectoryId a(1), b(2), c(3), d(4), e(5);
  AnchorGroups groups;
  groups.CreateGroup(b, 100);
  groups.Join(c, b);
  groups.CreateGroup(d, 200);
  groups.Join(e, d);
  EXPECT_TRUE(groups.SameGroup(b, c));
  EXPECT_FALSE(groups.SameGroup(c, e));
  EXPECT_FALSE(groups.Contains(a));
  groups.Join(a, c);  // A meets C
  EXPECT_EQ(groups.Root(a), b);
  const AnchorGroups::Merge merge = groups.MergeGroups(e, a);  // E meets A
  EXPECT_EQ(merge.surviving_root, b);
  EXPECT_EQ(merge.absorbed_root, d);
  EXPECT_EQ(merge.absorbed_prior_id, 200);
  for (TrajectoryId t : {a, b, c, d, e}) EXPECT_EQ(groups.Root(t), b);
  EXPECT_EQ(groups.PriorOf(e), 100);
}

}  // namespace
}  // namespace anchormap
