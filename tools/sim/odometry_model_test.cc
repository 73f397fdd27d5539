#include "tools/sim/odometry_model.h"

#include <cmath>

#include <gtest/gtest.h>

namespace anchormap::sim {
namespace {

OdometryNoiseOptions NoNoise() {
  OdometryNoiseOptions options;
  options.translation_noise_m_per_sqrt_m = 0.0;
  options.rotation_noise_rad_per_sqrt_m = 0.0;
  options.rotation_noise_rad_per_sqrt_rad = 0.0;
  options.scale_error_stddev = 0.0;
  return options;
}

TEST(NoisyOdometryTest, WithoutNoiseItIntegratesTheTrueMotion) {
  NoisyOdometry odometry(NoNoise(), Rng(1));
  Pose2 truth;
  for (int i = 0; i < 400; ++i) {
    const Pose2 step(0.01 + 0.001 * (i % 7), 0.0, 0.004 * ((i % 11) - 5));
    truth = Compose(truth, step);
    odometry.Integrate(step);
  }
  EXPECT_NEAR(odometry.pose().x(), truth.x(), 1e-12);
  EXPECT_NEAR(odometry.pose().y(), truth.y(), 1e-12);
  EXPECT_NEAR(odometry.pose().theta(), truth.theta(), 1e-12);
}

TEST(NoisyOdometryTest, StandingStillNeverDrifts) {
  NoisyOdometry odometry(OdometryNoiseOptions{}, Rng(3));
  for (int i = 0; i < 1000; ++i) odometry.Integrate(Pose2());
  EXPECT_EQ(odometry.pose().x(), 0.0);
  EXPECT_EQ(odometry.pose().y(), 0.0);
  EXPECT_EQ(odometry.pose().theta(), 0.0);
}

// 10 m straight in 500 steps, many robots: the final errors have the configured spread,
// independent of the step count (the noise is a random walk in distance).
TEST(NoisyOdometryTest, DriftStatisticsMatchTheNoiseDensities) {
  OdometryNoiseOptions options = NoNoise();
  options.translation_noise_m_per_sqrt_m = 0.02;
  options.rotation_noise_rad_per_sqrt_m = 0.01;
  const int robots = 2000;
  const int steps = 500;
  const double distance = 10.0;
  double sum_theta_sq = 0.0;
  double sum_x = 0.0;
  double sum_x_sq = 0.0;
  for (int r = 0; r < robots; ++r) {
    NoisyOdometry odometry(options, Rng(1000 + r));
    for (int i = 0; i < steps; ++i) odometry.Integrate(Pose2(distance / steps, 0.0, 0.0));
    const double x_error = odometry.pose().x() - distance;
    sum_x += x_error;
    sum_x_sq += x_error * x_error;
    sum_theta_sq += odometry.pose().theta() * odometry.pose().theta();
  }
  // Heading: random walk with 0.01 rad per sqrt(m) -> std 0.01 * sqrt(10) = 0.0316 rad.
  EXPECT_NEAR(std::sqrt(sum_theta_sq / robots), 0.01 * std::sqrt(distance), 0.0025);
  // Along-track: 0.02 m per sqrt(m) -> std 0.063 m, unbiased (heading errors shorten x
  // only to second order: ~ -0.002 m).
  EXPECT_NEAR(sum_x / robots, 0.0, 0.006);
  EXPECT_NEAR(std::sqrt(sum_x_sq / robots), 0.02 * std::sqrt(distance), 0.005);
}

TEST(NoisyOdometryTest, ScaleErrorIsConstantPerRobot) {
  OdometryNoiseOptions options = NoNoise();
  options.scale_error_stddev = 0.01;
  NoisyOdometry odometry(options, Rng(5));
  EXPECT_NE(odometry.scale_error(), 0.0);
  for (int i = 0; i < 100; ++i) odometry.Integrate(Pose2(0.1, 0.0, 0.0));
  EXPECT_NEAR(odometry.pose().x(), 10.0 * (1.0 + odometry.scale_error()), 1e-9);
  // Spread over robots.
  double sum_sq = 0.0;
  for (int r = 0; r < 4000; ++r) {
    const double e = NoisyOdometry(options, Rng(r)).scale_error();
    sum_sq += e * e;
  }
  EXPECT_NEAR(std::sqrt(sum_sq / 4000), 0.01, 0.0005);
}

TEST(NoisyOdometryTest, ValidateRejectsNegativeNoise) {
  EXPECT_TRUE(OdometryNoiseOptions{}.Validate().ok());
  OdometryNoiseOptions bad;
  bad.translation_noise_m_per_sqrt_m = -1.0;
  EXPECT_FALSE(bad.Validate().ok());
}

}  // namespace
}  // namespace anchormap::sim
