#include "tools/sim/encounter_detector.h"

#include <cmath>

#include <gtest/gtest.h>

namespace anchormap::sim {
namespace {

// An open square [0, 20]^2 with a wall x = 10 for y in [0, 10].
World Arena() {
  return World({{{0, 0}, {20, 0}},
                {{20, 0}, {20, 20}},
                {{20, 20}, {0, 20}},
                {{0, 20}, {0, 0}},
                {{10, 0}, {10, 10}}});
}

std::vector<Rng> Rngs(int n) {
  std::vector<Rng> rngs;
  for (int i = 0; i < n; ++i) rngs.emplace_back(7, i, RngStream::kEncounter);
  return rngs;
}

TEST(EncounterDetectorTest, BothRobotsSeeEachOtherWithTheRelativePose) {
  EncounterDetector detector(EncounterOptions{}, 2);
  auto rngs = Rngs(2);
  const std::vector<Pose2> poses = {Pose2(2, 15, 0.0), Pose2(5, 16, kPi / 2)};
  const auto encounters = detector.Detect(1000, Arena(), poses, rngs);
  ASSERT_EQ(encounters.size(), 2u);
  EXPECT_EQ(encounters[0].observer, 0);
  EXPECT_EQ(encounters[0].observed, 1);
  EXPECT_EQ(encounters[1].observer, 1);
  EXPECT_EQ(encounters[0].utime, 1000);
  // B seen from A: 3 m ahead, 1 m left, turned by 90 degrees.
  const Pose2& truth = encounters[0].T_observer_observed_true;
  EXPECT_NEAR(truth.x(), 3.0, 1e-12);
  EXPECT_NEAR(truth.y(), 1.0, 1e-12);
  EXPECT_NEAR(truth.theta(), kPi / 2, 1e-12);
  // The measurement is noisy but within 5 sigma, with the configured covariance.
  const Pose2& measured = encounters[0].T_observer_observed;
  EXPECT_NE(measured.x(), truth.x());
  EXPECT_NEAR(measured.x(), truth.x(), 5 * 0.05);
  EXPECT_NEAR(measured.theta(), truth.theta(), 5 * 0.02);
  EXPECT_DOUBLE_EQ(encounters[0].covariance(0, 0), 0.05 * 0.05);
  EXPECT_DOUBLE_EQ(encounters[0].covariance(2, 2), 0.02 * 0.02);
  EXPECT_DOUBLE_EQ(encounters[0].covariance(0, 1), 0.0);
}

TEST(EncounterDetectorTest, NoEncounterThroughAWallOrBeyondRange) {
  EncounterDetector detector(EncounterOptions{}, 2);
  auto rngs = Rngs(2);
  // 3 m apart, with the wall x = 10 between them.
  EXPECT_TRUE(detector.Detect(0, Arena(), {Pose2(8.5, 5, 0), Pose2(11.5, 5, 0)}, rngs).empty());
  // 6 m apart in the open.
  EXPECT_TRUE(detector.Detect(0, Arena(), {Pose2(2, 15, 0), Pose2(8, 15, 0)}, rngs).empty());
  // Just above the wall's end, in sight.
  EXPECT_EQ(detector.Detect(0, Arena(), {Pose2(8.5, 11, 0), Pose2(11.5, 11, 0)}, rngs).size(), 2u);
}

TEST(EncounterDetectorTest, AtMostOncePerPeriodPerOrderedPair) {
  EncounterDetector detector(EncounterOptions{}, 2);  // period 2 s
  auto rngs = Rngs(2);
  const std::vector<Pose2> poses = {Pose2(2, 15, 0.0), Pose2(4, 15, 0.0)};
  EXPECT_EQ(detector.Detect(0, Arena(), poses, rngs).size(), 2u);
  EXPECT_EQ(detector.Detect(1000000, Arena(), poses, rngs).size(), 0u);
  EXPECT_EQ(detector.Detect(1999999, Arena(), poses, rngs).size(), 0u);
  EXPECT_EQ(detector.Detect(2000000, Arena(), poses, rngs).size(), 2u);
}

TEST(EncounterDetectorTest, FieldOfViewLimitsTheObserver) {
  EncounterOptions options;
  options.field_of_view_deg = 90.0;
  EncounterDetector detector(options, 2);
  auto rngs = Rngs(2);
  // A looks east at B; B also looks east, so A is behind B.
  const auto encounters = detector.Detect(0, Arena(), {Pose2(2, 15, 0.0), Pose2(4, 15, 0.0)}, rngs);
  ASSERT_EQ(encounters.size(), 1u);
  EXPECT_EQ(encounters[0].observer, 0);
}

TEST(EncounterDetectorTest, ValidateRejectsZeroSigma) {
  EXPECT_TRUE(EncounterOptions{}.Validate().ok());
  EncounterOptions bad;
  bad.sigma_xy_m = 0.0;
  EXPECT_FALSE(bad.Validate().ok());
}

}  // namespace
}  // namespace anchormap::sim
