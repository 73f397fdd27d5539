#include "tools/bench/area_node_selector.h"

#include <cmath>

#include <gtest/gtest.h>

namespace anchormap {
namespace {

TEST(AreaNodeSelectorTest, ADriveOverAMappedLineAddsNodesOnlyWhereNoneIsNear) {
  AreaNodeSelector selector({1.0, 0.5});
  // Eastwards, a keyframe every 0.3 m from 0 to 3 m: nodes at 0, 1.2, 2.4 m.
  std::vector<int> folded_onto;
  for (int i = 0; i <= 10; ++i) folded_onto.push_back(selector.Add(0, Pose2(0.3 * i, 0.0, 0.0)));
  EXPECT_EQ(selector.num_nodes(), 3);
  EXPECT_EQ(folded_onto, (std::vector<int>{-1, 0, 0, 0, -1, 1, 1, 1, -1, 2, 2}));
  EXPECT_DOUBLE_EQ(selector.node(1).pose.x(), 1.2);
  // The same line again, eastwards, 5 cm off: nothing new; each folds onto the nearest node.
  EXPECT_EQ(selector.Add(0, Pose2(1.0, 0.05, 0.1)), 1);
  EXPECT_EQ(selector.Add(0, Pose2(2.9, 0.05, -0.1)), 2);
  EXPECT_EQ(selector.num_nodes(), 3);
  // Westwards (another view of the same place): a new node.
  EXPECT_EQ(selector.Add(0, Pose2(1.2, 0.0, M_PI)), -1);
  EXPECT_EQ(selector.num_nodes(), 4);
  // Just outside the angle (0.5 rad) of node 0 and the radius of node 1: a new node.
  EXPECT_EQ(selector.Add(0, Pose2(0.1, 0.0, 0.51)), -1);
  EXPECT_EQ(selector.Add(0, Pose2(2.41, 1.2, 0.0)), -1);
  EXPECT_EQ(selector.num_nodes(), 6);
}

TEST(AreaNodeSelectorTest, AnIneligibleNodeIsSkippedForTheNextNearest) {
  AreaNodeSelector selector({1.0, 0.5});
  ASSERT_EQ(selector.Add(1, Pose2(0.0, 0.0, 0.0)), -1);
  ASSERT_EQ(selector.Add(2, Pose2(0.0, 1.5, 0.0)), -1);
  // Nearest is keyframe 2's node (0.4 m); with only keyframe 1's eligible, node 0 (1.1 m)
  // is out of reach: a new node.
  const auto only_keyframe_1 = [](const AreaNodeSelector::Node& n) { return n.keyframe == 1; };
  EXPECT_EQ(selector.Add(3, Pose2(0.0, 1.1, 0.0)), 1);
  EXPECT_EQ(selector.Add(3, Pose2(0.0, 1.1, 0.0), only_keyframe_1), -1);
  // Across cell borders (cells are 1 m wide) and negative coordinates alike.
  EXPECT_EQ(selector.Add(1, Pose2(-0.9, -0.2, 0.0), only_keyframe_1), 0);
  EXPECT_EQ(selector.num_nodes(), 3);
}

}  // namespace
}  // namespace anchormap
