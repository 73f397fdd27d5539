#include "agent/keyframer.h"

#include <gtest/gtest.h>

namespace anchormap {
namespace {

TEST(KeyframerTest, FirstScanThenDistanceAngleAndTimeThresholds) {
  KeyframerOptions options;
  options.max_distance_m = 0.5;
  options.max_angle_rad = 0.3;
  options.max_interval_s = 2.0;
  ASSERT_TRUE(options.Validate().ok());
  Keyframer keyframer(options);
  EXPECT_TRUE(keyframer.ShouldMake(Pose2(), 0));
  keyframer.Accept(Pose2(1, 1, 0.5), 0);
  EXPECT_FALSE(keyframer.ShouldMake(Pose2(1.3, 1.3, 0.5), 100'000));  // 0.42 m
  EXPECT_TRUE(keyframer.ShouldMake(Pose2(1.3, 1.5, 0.5), 100'000));   // 0.58 m
  EXPECT_FALSE(keyframer.ShouldMake(Pose2(1, 1, 0.79), 100'000));     // 0.29 rad
  EXPECT_TRUE(keyframer.ShouldMake(Pose2(1, 1, 0.2), 100'000));       // -0.3 rad
  EXPECT_FALSE(keyframer.ShouldMake(Pose2(1, 1, 0.5), 1'999'999));
  EXPECT_TRUE(keyframer.ShouldMake(Pose2(1, 1, 0.5), 2'000'000));
}

TEST(KeyframerTest, AngleThresholdWrapsAroundPi) {
  Keyframer keyframer;
  keyframer.Accept(Pose2(0, 0, 3.1), 0);
  EXPECT_FALSE(keyframer.ShouldMake(Pose2(0, 0, -3.1), 1000));  // 0.08 rad apart
}

TEST(KeyframerTest, ForcedKeyframeAtOrAfterATime) {
  Keyframer keyframer;
  keyframer.Accept(Pose2(), 0);
  keyframer.ForceAtOrAfter(500'000);
  EXPECT_TRUE(keyframer.force_pending());
  EXPECT_FALSE(keyframer.ShouldMake(Pose2(), 400'000));
  EXPECT_TRUE(keyframer.ShouldMake(Pose2(), 500'000));
  keyframer.Accept(Pose2(), 500'000);
  EXPECT_FALSE(keyframer.force_pending());
  EXPECT_FALSE(keyframer.ShouldMake(Pose2(), 600'000));
}

TEST(KeyframerTest, TimeLimitZeroDisablesIt) {
  KeyframerOptions options;
  options.max_interval_s = 0;
  Keyframer keyframer(options);
  keyframer.Accept(Pose2(), 0);
  EXPECT_FALSE(keyframer.ShouldMake(Pose2(), 3'600'000'000));
  options.max_distance_m = -1;
  EXPECT_FALSE(options.Validate().ok());
}

}  // namespace
}  // namespace anchormap
