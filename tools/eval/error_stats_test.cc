#include "tools/eval/error_stats.h"

#include <cmath>

#include <gtest/gtest.h>

namespace anchormap {
namespace {

TEST(ErrorStatsTest, HandComputedValues) {
  // 1, 2, 3, 6: mean 3, squares 1 + 4 + 9 + 36 = 50, rmse sqrt(12.5), deviations -2 -1 0 3,
  // sample variance (4 + 1 + 0 + 9) / 3 = 14 / 3, median (2 + 3) / 2.
  const ErrorStats s = ComputeErrorStats({6.0, 1.0, 3.0, 2.0});
  EXPECT_EQ(s.count, 4);
  EXPECT_DOUBLE_EQ(s.mean, 3.0);
  EXPECT_DOUBLE_EQ(s.rmse, std::sqrt(12.5));
  EXPECT_DOUBLE_EQ(s.std, std::sqrt(14.0 / 3.0));
  EXPECT_DOUBLE_EQ(s.median, 2.5);
  EXPECT_EQ(s.min, 1.0);
  EXPECT_EQ(s.max, 6.0);
}

TEST(ErrorStatsTest, OneAndNone) {
  const ErrorStats one = ComputeErrorStats({0.5});
  EXPECT_EQ(one.count, 1);
  EXPECT_EQ(one.std, 0.0);
  EXPECT_EQ(one.median, 0.5);
  const ErrorStats none = ComputeErrorStats({});
  EXPECT_EQ(none.count, 0);
  EXPECT_EQ(none.mean, 0.0);
}

}  // namespace
}  // namespace anchormap
