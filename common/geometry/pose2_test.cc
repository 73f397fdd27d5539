#include "common/geometry/pose2.h"

#include <random>

#include <gtest/gtest.h>

#include "common/geometry/numeric_diff.h"

namespace anchormap {
namespace {

// Hard values: angles at and around +-pi, zero, large translations.
std::vector<Pose2> HardPoses() {
  std::vector<Pose2> poses = {Pose2(0, 0, 0),
                              Pose2(1, 2, kPi),
                              Pose2(-3, 0.5, -kPi + 1e-9),
                              Pose2(1e3, -1e3, kPi / 2),
                              Pose2(0.1, -0.2, -kPi / 2),
                              Pose2(5, 5, 3.0)};
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u(-10, 10), a(-kPi, kPi);
  for (int i = 0; i < 20; ++i) {
    // One draw per statement: a call's argument order is unspecified (gcc's order kept).
    const double theta = a(rng);
    const double y = u(rng);
    const double x = u(rng);
    poses.emplace_back(x, y, theta);
  }
  return poses;
}

TEST(AngleTest, WrapsIntoHalfOpenInterval) {
  EXPECT_DOUBLE_EQ(WrapAngle(kPi), kPi);
  EXPECT_DOUBLE_EQ(WrapAngle(-kPi), kPi);
  EXPECT_NEAR(WrapAngle(3 * kPi), kPi, 1e-12);
  EXPECT_NEAR(WrapAngle(2 * kPi + 0.5), 0.5, 1e-12);
  EXPECT_NEAR(WrapAngle(-2 * kPi - 0.5), -0.5, 1e-12);
  EXPECT_NEAR(AngleDifference(kPi - 0.1, -kPi + 0.1), -0.2, 1e-12);
}

TEST(Pose2Test, ComposeMatchesAlgorithmFormula) {
  const Pose2 b(1.0, 2.0, kPi / 2), d(3.0, 0.5, 0.25);
  const Pose2 p = Compose(b, d);
  EXPECT_NEAR(p.x(), 1.0 - 0.5, 1e-12);
  EXPECT_NEAR(p.y(), 2.0 + 3.0, 1e-12);
  EXPECT_NEAR(p.theta(), kPi / 2 + 0.25, 1e-12);
}

// With the first pose's cos and sin given (computed once for many poses), Compose gives the
// same bits as computing them itself.
TEST(Pose2Test, ComposeWithGivenRotationHasTheSameBits) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> coordinate(-50.0, 50.0), angle(-4.0, 4.0);
  int checked = 0;
  for (const Pose2& a : HardPoses()) {
    const CosSin rotation = CosSin::Of(a.theta());
    for (int k = 0; k < 200; ++k) {
      const Pose2 b(coordinate(rng), coordinate(rng), angle(rng));
      const Pose2 expected = Compose(a, b);
      const Pose2 actual = Compose(a, rotation, b);
      EXPECT_EQ(actual.x(), expected.x());
      EXPECT_EQ(actual.y(), expected.y());
      EXPECT_EQ(actual.theta(), expected.theta());
      ++checked;
    }
  }
  EXPECT_GT(checked, 0);
}

TEST(Pose2Test, BetweenInvertsCompose) {
  for (const Pose2& a : HardPoses()) {
    for (const Pose2& d : HardPoses()) {
      const Pose2 b = Compose(a, d);
      const Eigen::Vector3d error = PoseError(Between(a, b), d);
      EXPECT_LT(error.cwiseAbs().maxCoeff(), 1e-9);
    }
    const Eigen::Vector3d identity_error = PoseError(Compose(a, a.Inverse()), Pose2());
    EXPECT_LT(identity_error.cwiseAbs().maxCoeff(), 1e-9);
  }
}

TEST(Pose2Test, TransformPointAgreesWithCompose) {
  const Pose2 a(1, -2, 0.7);
  const Eigen::Vector2d p(0.3, 4.0);
  const Pose2 composed = Compose(a, Pose2(p.x(), p.y(), 0));
  EXPECT_LT((a.TransformPoint(p) - composed.translation()).norm(), 1e-12);
}

TEST(Pose2Test, JacobiansEqualNumericDifferences) {
  const auto poses = HardPoses();
  for (size_t i = 0; i + 1 < poses.size(); ++i) {
    const Pose2& a = poses[i];
    const Pose2& b = poses[i + 1];
    Eigen::Matrix3d Ja, Jb;
    Compose(a, b, &Ja, &Jb);
    Eigen::VectorXd x(6);
    x << a.vector(), b.vector();
    auto compose = [](const Eigen::VectorXd& v) {
      return Compose(Pose2::FromVector(v.head<3>()), Pose2::FromVector(v.tail<3>())).vector();
    };
    auto numeric = NumericJacobian(compose, x);
    EXPECT_LT((numeric.leftCols<3>() - Ja).cwiseAbs().maxCoeff(),
              1e-6 * (1 + a.vector().norm() + b.vector().norm()));
    EXPECT_LT((numeric.rightCols<3>() - Jb).cwiseAbs().maxCoeff(), 1e-6);

    Between(a, b, &Ja, &Jb);
    auto between = [](const Eigen::VectorXd& v) {
      return Between(Pose2::FromVector(v.head<3>()), Pose2::FromVector(v.tail<3>())).vector();
    };
    numeric = NumericJacobian(between, x);
    EXPECT_LT((numeric.leftCols<3>() - Ja).cwiseAbs().maxCoeff(),
              1e-6 * (1 + (a.vector() - b.vector()).norm()));
    EXPECT_LT((numeric.rightCols<3>() - Jb).cwiseAbs().maxCoeff(), 1e-6);
  }
}

TEST(InterpolateTest, LinearInPositionShortWayInTheta) {
  const Pose2 mid = Interpolate(Pose2(0, 0, 3.1), Pose2(2, -4, -3.1), 0.25);
  EXPECT_DOUBLE_EQ(mid.x(), 0.5);
  EXPECT_DOUBLE_EQ(mid.y(), -1.0);
  // 0.25 of the 0.083 rad arc through pi, not of the 6.2 rad arc through 0.
  EXPECT_NEAR(mid.theta(), WrapAngle(3.1 + 0.25 * (2 * kPi - 6.2)), 1e-12);
  const Pose2 a(1, 2, 0.3), b(-1, 5, -2.0);
  EXPECT_LT(PoseError(Interpolate(a, b, 0.0), a).norm(), 1e-15);
  EXPECT_LT(PoseError(Interpolate(a, b, 1.0), b).norm(), 1e-15);
}

TEST(QuaternionTest, YawRoundTripsAndHeadingOfATiltedQuaternion) {
  for (double yaw : {-3.0, -1.0, 0.0, 0.5, 3.1, kPi}) {
    double w, x, y, z;
    QuaternionOfYaw(yaw, &w, &x, &y, &z);
    EXPECT_NEAR(w, std::cos(yaw / 2), 1e-15);
    EXPECT_NEAR(AngleDifference(YawOfQuaternion(w, x, y, z), yaw), 0.0, 1e-12);
  }
  // Yaw 0.7 composed with a small roll: the heading is still 0.7.
  const double c = std::cos(0.35), s = std::sin(0.35), cr = std::cos(0.05), sr = std::sin(0.05);
  EXPECT_NEAR(YawOfQuaternion(c * cr, c * sr, s * sr, s * cr), 0.7, 1e-12);
}

}  // namespace
}  // namespace anchormap
