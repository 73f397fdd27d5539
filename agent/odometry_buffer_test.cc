#include "agent/odometry_buffer.h"

#include <gtest/gtest.h>

namespace anchormap {
namespace {

TEST(OdometryBufferTest, InterpolatesBetweenReadingsAndIsExactAtThem) {
  OdometryBuffer buffer;
  ASSERT_TRUE(buffer.Add({1'000'000, Pose2(0, 0, 0)}).ok());
  ASSERT_TRUE(buffer.Add({1'020'000, Pose2(0.02, 0.01, 0.04)}).ok());
  const auto exact = buffer.PoseAt(1'020'000);
  ASSERT_TRUE(exact);
  EXPECT_DOUBLE_EQ(exact->x(), 0.02);
  const auto middle = buffer.PoseAt(1'005'000);  // a quarter of the way
  ASSERT_TRUE(middle);
  EXPECT_DOUBLE_EQ(middle->x(), 0.005);
  EXPECT_DOUBLE_EQ(middle->y(), 0.0025);
  EXPECT_DOUBLE_EQ(middle->theta(), 0.01);
  EXPECT_FALSE(buffer.PoseAt(999'999));
  EXPECT_FALSE(buffer.PoseAt(1'020'001));
}

TEST(OdometryBufferTest, InterpolatesThetaTheShortWayAcrossPi) {
  OdometryBuffer buffer;
  ASSERT_TRUE(buffer.Add({0, Pose2(0, 0, 3.1)}).ok());
  ASSERT_TRUE(buffer.Add({100, Pose2(0, 0, -3.1)}).ok());
  EXPECT_NEAR(std::abs(buffer.PoseAt(50)->theta()), kPi, 1e-9);
}

TEST(OdometryBufferTest, RefusesOutOfOrderAndDuplicateTimes) {
  OdometryBuffer buffer;
  ASSERT_TRUE(buffer.Add({100, Pose2()}).ok());
  EXPECT_EQ(buffer.Add({100, Pose2(1, 0, 0)}).code(), ErrorCode::kOutOfOrder);
  EXPECT_EQ(buffer.Add({50, Pose2(1, 0, 0)}).code(), ErrorCode::kOutOfOrder);
  EXPECT_EQ(buffer.size(), 1u);
}

TEST(OdometryBufferTest, IsBoundedAndRefusesLongGaps) {
  OdometryBufferOptions options;
  options.capacity = 10;
  options.max_gap_s = 0.5;
  OdometryBuffer buffer(options);
  for (int i = 0; i < 25; ++i) ASSERT_TRUE(buffer.Add({i * 20'000, Pose2(0.01 * i, 0, 0)}).ok());
  EXPECT_EQ(buffer.size(), 10u);
  EXPECT_EQ(buffer.oldest_utime(), 15 * 20'000);
  EXPECT_FALSE(buffer.PoseAt(0));                             // dropped from the history
  ASSERT_TRUE(buffer.Add({2'000'000, Pose2(5, 0, 0)}).ok());  // 1.52 s after the last one
  EXPECT_FALSE(buffer.PoseAt(1'000'000));
  EXPECT_TRUE(buffer.PoseAt(2'000'000));
}

}  // namespace
}  // namespace anchormap
