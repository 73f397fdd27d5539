#include "tools/render/colors.h"

#include <set>

#include <gtest/gtest.h>

namespace anchormap::render {
namespace {

TEST(ColorsTest, FirstColoursAreDistinctAndNotGrey) {
  std::set<std::tuple<int, int, int>> seen;
  for (int i = 0; i < 60; ++i) {
    const Rgb c = TrajectoryColor(i);
    seen.insert({c.r, c.g, c.b});
    // Never a grey (the grid's colours): channels differ by at least 40.
    EXPECT_GT(std::max({c.r, c.g, c.b}) - std::min({c.r, c.g, c.b}), 40) << i;
  }
  EXPECT_EQ(seen.size(), 60u);
}

TEST(ColorsTest, NaturalOrderOfRobotNames) {
  EXPECT_TRUE((TrajectoryKey{"R2", 0} < TrajectoryKey{"R10", 0}));
  EXPECT_FALSE((TrajectoryKey{"R10", 0} < TrajectoryKey{"R2", 0}));
  EXPECT_TRUE((TrajectoryKey{"R2", 1} < TrajectoryKey{"R2", 5}));
  EXPECT_TRUE((TrajectoryKey{"ALPHA", 0} < TrajectoryKey{"BETA", 0}));
}

TEST(ColorsTest, AssignmentIsByNaturalOrderAndStable) {
  const ColorAssignment colors({{"R10", 3}, {"R2", 7}, {"R1", 1}, {"R2", 7}});
  EXPECT_EQ(colors.ColorOf({"R1", 1}), TrajectoryColor(0));
  EXPECT_EQ(colors.ColorOf({"R2", 7}), TrajectoryColor(1));
  EXPECT_EQ(colors.ColorOf({"R10", 3}), TrajectoryColor(2));
  EXPECT_EQ(colors.ColorOf({"R4", 1}), (Rgb{0, 0, 0}));  // unknown
}

}  // namespace
}  // namespace anchormap::render
