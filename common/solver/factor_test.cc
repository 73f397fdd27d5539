#include "common/solver/factor.h"

#include <cstring>
#include <random>

#include <gtest/gtest.h>

#include "common/geometry/numeric_diff.h"

namespace anchormap {
namespace {

// Checks every Jacobian of `factor` against central differences at `values`.
void ExpectJacobiansMatchNumeric(const Factor& factor, std::vector<Pose2> values) {
  const int n = static_cast<int>(values.size());
  std::array<Eigen::Matrix3d, kMaxFactorKeys> J;
  const Eigen::Vector3d error = std::visit(
      [&](const auto& f) -> Eigen::Vector3d {
        using T = std::decay_t<decltype(f)>;
        if constexpr (std::is_same_v<T, PriorFactor>) return f.Error(values[0], &J[0]);
        if constexpr (std::is_same_v<T, EncounterFactor>) {
          return f.Error(values[0], values[1], values[2], values[3], J.data());
        } else if constexpr (!std::is_same_v<T, PriorFactor>) {
          return f.Error(values[0], values[1], &J[0], &J[1]);
        }
        return {};
      },
      factor);
  ASSERT_TRUE(error.allFinite());
  Eigen::VectorXd x(3 * n);
  for (int k = 0; k < n; ++k) x.segment<3>(3 * k) = values[k].vector();
  auto f = [&](const Eigen::VectorXd& v) {
    std::vector<Pose2> at;
    for (int k = 0; k < n; ++k) at.push_back(Pose2::FromVector(v.segment<3>(3 * k)));
    return std::visit(
        [&](const auto& fac) -> Eigen::Vector3d {
          using T = std::decay_t<decltype(fac)>;
          if constexpr (std::is_same_v<T, PriorFactor>) return fac.Error(at[0], nullptr);
          if constexpr (std::is_same_v<T, EncounterFactor>) {
            return fac.Error(at[0], at[1], at[2], at[3], nullptr);
          } else if constexpr (!std::is_same_v<T, PriorFactor>) {
            return fac.Error(at[0], at[1], nullptr, nullptr);
          }
          return {};
        },
        factor);
  };
  const auto numeric = NumericJacobian(f, x, 1e-7);
  for (int k = 0; k < n; ++k) {
    EXPECT_LT((numeric.block<3, 3>(0, 3 * k) - J[k]).cwiseAbs().maxCoeff(), 1e-5)
        << "key " << k << "\nanalytic\n"
        << J[k] << "\nnumeric\n"
        << numeric.block<3, 3>(0, 3 * k);
  }
}

std::vector<Pose2> RandomPoses(std::mt19937* rng, int n) {
  std::uniform_real_distribution<double> u(-20, 20), a(-kPi, kPi);
  std::vector<Pose2> poses;
  for (int k = 0; k < n; ++k) {
    // One draw per statement: a call's argument order is unspecified (gcc's order kept).
    const double theta = a(*rng);
    const double y = u(*rng);
    const double x = u(*rng);
    poses.emplace_back(x, y, theta);
  }
  return poses;
}

TEST(FactorTest, AllJacobiansEqualNumericDifferences) {
  std::mt19937 rng(3);
  const PoseKey a{TrajectoryId(0), 3}, b{TrajectoryId(1), 5};
  for (int trial = 0; trial < 50; ++trial) {
    const Pose2 z = RandomPoses(&rng, 1)[0];
    ExpectJacobiansMatchNumeric(PriorFactor{a, z, Eigen::Matrix3d::Identity()},
                                RandomPoses(&rng, 1));
    ExpectJacobiansMatchNumeric(
        BetweenFactor{a, {TrajectoryId(0), 4}, z, Eigen::Matrix3d::Identity()},
        RandomPoses(&rng, 2));
    ExpectJacobiansMatchNumeric(GlobalEncounterFactor{a, b, z, Eigen::Matrix3d::Identity()},
                                RandomPoses(&rng, 2));
    ExpectJacobiansMatchNumeric(EncounterFactor{a, b, z, Eigen::Matrix3d::Identity()},
                                RandomPoses(&rng, 4));
  }
}

// The gradient passes give each value's cos and sin: the same bits as without them.
TEST(FactorTest, LinearizeWithGivenRotationsIsBitForBitTheSame) {
  std::mt19937 rng(5);
  const PoseKey a{TrajectoryId(0), 3}, b{TrajectoryId(1), 5};
  const Eigen::Matrix3d S = Eigen::Vector3d(10.0, 20.0, 30.0).asDiagonal();
  for (int trial = 0; trial < 50; ++trial) {
    const Pose2 z = RandomPoses(&rng, 1)[0];
    const std::vector<Pose2> values = RandomPoses(&rng, 4);
    std::array<CosSin, kMaxFactorKeys> rotations;
    for (int k = 0; k < 4; ++k) rotations[k] = CosSin::Of(values[k].theta());
    for (const Factor& factor :
         {Factor(PriorFactor{a, z, S}), Factor(BetweenFactor{a, {TrajectoryId(0), 4}, z, S}),
          Factor(GlobalEncounterFactor{a, b, z, S}), Factor(EncounterFactor{a, b, z, S})}) {
      const LinearizedFactor plain = Linearize(factor, values.data());
      const LinearizedFactor given = Linearize(factor, values.data(), rotations.data());
      ASSERT_EQ(plain.num_keys, given.num_keys);
      for (int k = 0; k < plain.num_keys; ++k) {
        EXPECT_EQ(
            std::memcmp(plain.jacobians[k].data(), given.jacobians[k].data(), 9 * sizeof(double)),
            0);
      }
      EXPECT_EQ(
          std::memcmp(plain.whitened_error.data(), given.whitened_error.data(), 3 * sizeof(double)),
          0);
    }
  }
}

TEST(FactorTest, EncounterPredictsRelativeGlobalPose) {
  // Anchors and local poses chosen so that the global poses are known.
  const Pose2 A_a(1, 2, 0.3), A_b(-4, 0.5, -1.2), x_a(3, -1, 2.0), x_b(0.5, 0.5, -2.9);
  const Pose2 z = Between(Compose(A_a, x_a), Compose(A_b, x_b));
  const EncounterFactor f{
      {TrajectoryId(0), 0}, {TrajectoryId(1), 0}, z, Eigen::Matrix3d::Identity()};
  EXPECT_LT(f.Error(x_a, x_b, A_a, A_b, nullptr).norm(), 1e-12);
  EXPECT_EQ(f.keys()[2], Key(AnchorKey{TrajectoryId(0)}));
  EXPECT_EQ(f.keys()[3], Key(AnchorKey{TrajectoryId(1)}));
}

TEST(FactorTest, LinearizeWhitens) {
  Eigen::Matrix3d S = Eigen::Matrix3d::Identity() * 10;
  const PriorFactor prior{PoseKey{TrajectoryId(0), 0}, Pose2(1, 0, 0), S};
  const Pose2 value(1.5, 0, 0);
  const LinearizedFactor lin = Linearize(prior, &value);
  EXPECT_NEAR(lin.whitened_error.x(), 5.0, 1e-12);
  EXPECT_NEAR(FactorChi2(prior, &value), 25.0, 1e-12);
  EXPECT_EQ(lin.jacobians[0], S);
}

}  // namespace
}  // namespace anchormap
