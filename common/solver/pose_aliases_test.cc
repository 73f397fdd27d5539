#include "common/solver/pose_aliases.h"

#include <gtest/gtest.h>

#include "common/geometry/numeric_diff.h"
#include "common/solver/smoother.h"

namespace anchormap {
namespace {

const TrajectoryId kR1(0), kR2(1);

Eigen::Matrix3d Diagonal(double sigma_m, double sigma_rad) {
  return Eigen::Vector3d(sigma_m * sigma_m, sigma_m * sigma_m, sigma_rad * sigma_rad).asDiagonal();
}

void ExpectNear(const Pose2& a, const Pose2& b, double tolerance) {
  EXPECT_NEAR(a.x(), b.x(), tolerance);
  EXPECT_NEAR(a.y(), b.y(), tolerance);
  EXPECT_NEAR(a.theta(), b.theta(), tolerance);
}

TEST(PoseAliasesTest, InverseJacobianMatchesCentralDifferences) {
  const Pose2 p(1.5, -0.7, 0.9);
  const auto inverse = [](const Eigen::VectorXd& v) {
    return Pose2(v[0], v[1], v[2]).Inverse().vector();
  };
  const Eigen::MatrixXd numeric = NumericJacobian(inverse, p.vector());
  EXPECT_LT((InverseJacobian(p) - numeric).cwiseAbs().maxCoeff(), 1e-7);
}

TEST(PoseAliasesTest, MeasurementBetweenTwoFoldedKeysGoesBetweenTheirNodes) {
  const PoseAlias a{PoseKey{kR1, 3}, Pose2(0.4, 0.1, 0.2), Diagonal(0.01, 0.002)};
  const PoseAlias b{PoseKey{kR1, 7}, Pose2(-0.3, 0.5, -0.4), Diagonal(0.02, 0.004)};
  const Pose2 z(1.0, 0.2, 0.3);
  const Eigen::Matrix3d z_covariance = Diagonal(0.05, 0.01);
  const NodeMeasurement m = MapToNodes(PoseKey{kR1, 10}, &a, PoseKey{kR1, 11}, &b, z, z_covariance);
  EXPECT_EQ(m.a, (PoseKey{kR1, 3}));
  EXPECT_EQ(m.b, (PoseKey{kR1, 7}));
  EXPECT_FALSE(m.inside_one_node());
  // node_a (+) offset_a (+) z = node_b (+) offset_b.
  ExpectNear(m.measured_T_a_b, Compose(Compose(a.T_node_key, z), b.T_node_key.Inverse()), 1e-12);
  // The covariance: z's propagated plus twice each offset's, checked by central differences.
  const auto f = [](const Eigen::VectorXd& v) {
    return Compose(Compose(Pose2(v[0], v[1], v[2]), Pose2(v[3], v[4], v[5])),
                   Pose2(v[6], v[7], v[8]).Inverse())
        .vector();
  };
  Eigen::VectorXd x(9);
  x << a.T_node_key.vector(), z.vector(), b.T_node_key.vector();
  const Eigen::MatrixXd J = NumericJacobian(f, x);
  Eigen::MatrixXd sigma = Eigen::MatrixXd::Zero(9, 9);
  sigma.block<3, 3>(0, 0) = 2.0 * a.covariance;
  sigma.block<3, 3>(3, 3) = z_covariance;
  sigma.block<3, 3>(6, 6) = 2.0 * b.covariance;
  const Eigen::Matrix3d expected = J * sigma * J.transpose();
  EXPECT_LT((m.covariance - expected).cwiseAbs().maxCoeff(), 1e-9);
  // Doubled offsets: larger than z's own covariance on every axis.
  for (int i = 0; i < 3; ++i) EXPECT_GT(m.covariance(i, i), z_covariance(i, i));
}

TEST(PoseAliasesTest, KeysFoldedOntoOneNodeAddNothing) {
  const PoseAlias a{PoseKey{kR1, 3}, Pose2(0.4, 0.1, 0.2), Diagonal(0.01, 0.002)};
  const PoseAlias b{PoseKey{kR1, 3}, Pose2(0.9, 0.1, 0.2), Diagonal(0.01, 0.002)};
  EXPECT_TRUE(
      MapToNodes(PoseKey{kR1, 10}, &a, PoseKey{kR1, 11}, &b, Pose2(0.5, 0, 0), Diagonal(0.05, 0.01))
          .inside_one_node());
}

TEST(PoseAliasesTest, KeysWithoutAliasKeepTheirMeasurement) {
  const Pose2 z(1.0, 0.2, 0.3);
  const Eigen::Matrix3d covariance = Diagonal(0.05, 0.01);
  const NodeMeasurement m =
      MapToNodes(PoseKey{kR1, 1}, nullptr, PoseKey{kR2, 2}, nullptr, z, covariance);
  EXPECT_EQ(m.a, (PoseKey{kR1, 1}));
  EXPECT_EQ(m.b, (PoseKey{kR2, 2}));
  ExpectNear(m.measured_T_a_b, z, 1e-15);
  EXPECT_LT((m.covariance - covariance).cwiseAbs().maxCoeff(), 1e-15);
}

// R1: poses 0, 1 (1 m apart); key 2 folds onto pose 0, key 3 onto pose 1.
class SmootherAliasTest : public ::testing::Test {
 protected:
  void SetUp() override {
    ASSERT_TRUE(smoother.AddPose({kR1, 0}, Pose2()).ok());
    ASSERT_TRUE(smoother.AddPose({kR1, 1}, Pose2(1, 0, 0)).ok());
    ASSERT_TRUE(smoother.AddBetween({kR1, 0}, {kR1, 1}, Pose2(1, 0, 0), odometry).ok());
    ASSERT_TRUE(smoother.Update().status.ok());
  }
  Smoother smoother;
  const Eigen::Matrix3d odometry = Diagonal(0.05, 0.01);
  const Eigen::Matrix3d match = Diagonal(0.01, 0.002);
};

TEST_F(SmootherAliasTest, AnAliasAnswersAsItsNodeComposedWithTheOffset) {
  const Pose2 offset(0.1, 0.2, 0.3);
  ASSERT_TRUE(smoother.AddAlias({kR1, 2}, {kR1, 0}, offset, match).ok());
  EXPECT_TRUE(smoother.HasPose({kR1, 2}));
  EXPECT_FALSE(smoother.HasVariable(Key(PoseKey{kR1, 2})));
  EXPECT_EQ(smoother.NumPoses(kR1), 3);
  EXPECT_EQ(smoother.NumAliases(), 1);
  EXPECT_EQ(smoother.stats().variables, 2);
  ExpectNear(smoother.FramePose({kR1, 2}), Compose(smoother.FramePose({kR1, 0}), offset), 1e-15);
  ExpectNear(smoother.GlobalPose({kR1, 2}), smoother.FramePose({kR1, 2}), 1e-15);
  ASSERT_EQ(smoother.GlobalTrajectory(kR1).size(), 3u);
  // The alias's covariance: its node's, moved by the offset (not the offset's own).
  Eigen::Matrix3d J_node, J_offset;
  Compose(smoother.FramePose({kR1, 0}), offset, &J_node, &J_offset);
  const Eigen::Matrix3d node = smoother.MarginalCovariance(PoseKey{kR1, 0});
  const Eigen::Matrix3d alias = smoother.MarginalCovariance(PoseKey{kR1, 2});
  EXPECT_LT((alias - J_node * node * J_node.transpose()).cwiseAbs().maxCoeff(), 1e-12);
  EXPECT_LT((smoother.ProjectedCovariance({PoseKey{kR1, 2}}, {Eigen::Matrix3d::Identity()}) - alias)
                .cwiseAbs()
                .maxCoeff(),
            1e-12);
  EXPECT_TRUE(smoother.IsSolved(PoseKey{kR1, 2}));
  // Refusals: an alias key taken, an alias of an alias, an alias as a new pose.
  EXPECT_FALSE(smoother.AddAlias({kR1, 2}, {kR1, 1}, offset, match).ok());
  EXPECT_FALSE(smoother.AddAlias({kR1, 3}, {kR1, 2}, offset, match).ok());
  EXPECT_FALSE(smoother.AddPose({kR1, 2}, Pose2()).ok());
}

TEST_F(SmootherAliasTest, OdometryBetweenFoldedKeysBecomesAFactorBetweenTheirNodes) {
  // Key 2 sits 0.2 m ahead of pose 1 and key 3 0.2 m ahead of pose 0 (driving back): the
  // odometry 2 -> 3 (-1 m) is a second measurement of pose 0 from pose 1.
  ASSERT_TRUE(smoother.AddAlias({kR1, 2}, {kR1, 1}, Pose2(0.2, 0, 0), match).ok());
  ASSERT_TRUE(smoother.AddAlias({kR1, 3}, {kR1, 0}, Pose2(0.2, 0, 0), match).ok());
  const int64_t factors = smoother.stats().factors;
  ASSERT_TRUE(smoother.AddBetween({kR1, 2}, {kR1, 3}, Pose2(-0.9, 0, 0), odometry).ok());
  EXPECT_EQ(smoother.stats().factors, factors + 1);
  ASSERT_TRUE(smoother.Update().status.ok());
  // Two measurements of the 1 m: 1.0 (odometry) and 0.2 + 0.9 - 0.2 = 0.9 (the mapped one).
  const double gap = smoother.FramePose({kR1, 1}).x() - smoother.FramePose({kR1, 0}).x();
  EXPECT_GT(gap, 0.9);
  EXPECT_LT(gap, 1.0);
  // Key 4 folds onto pose 0 too: the odometry 3 -> 4 is inside one node and adds nothing.
  ASSERT_TRUE(smoother.AddAlias({kR1, 4}, {kR1, 0}, Pose2(0.3, 0, 0), match).ok());
  ASSERT_TRUE(smoother.AddBetween({kR1, 3}, {kR1, 4}, Pose2(0.1, 0, 0), odometry).ok());
  EXPECT_EQ(smoother.stats().factors, factors + 1);
  EXPECT_EQ(smoother.measurements_inside_nodes(), 1);
}

TEST_F(SmootherAliasTest, ANewPoseAfterAnAliasIsTiedToTheAliasNode) {
  ASSERT_TRUE(smoother.AddAlias({kR1, 2}, {kR1, 1}, Pose2(0.2, 0, 0), match).ok());
  const Pose2 initial = Compose(smoother.FramePose({kR1, 2}), Pose2(1, 0, 0));
  ASSERT_TRUE(smoother.AddPose({kR1, 3}, initial).ok());
  ASSERT_TRUE(smoother.AddBetween({kR1, 2}, {kR1, 3}, Pose2(1, 0, 0), odometry).ok());
  const UpdateResult result = smoother.Update();
  ASSERT_TRUE(result.status.ok()) << result.status.message();
  EXPECT_NEAR(smoother.FramePose({kR1, 3}).x(), 2.2, 1e-6);
  EXPECT_TRUE(smoother.HasCovariance(PoseKey{kR1, 3}));
}

TEST_F(SmootherAliasTest, AcrossTrajectoriesOnlyInOneAnchoredGroup) {
  ASSERT_TRUE(smoother.AddPose({kR2, 0}, Pose2()).ok());
  ASSERT_TRUE(smoother.AddPose({kR2, 1}, Pose2(1, 0, 0)).ok());
  ASSERT_TRUE(smoother.AddBetween({kR2, 0}, {kR2, 1}, Pose2(1, 0, 0), odometry).ok());
  EXPECT_FALSE(smoother.AddAlias({kR2, 2}, {kR1, 1}, Pose2(), match).ok());
  // R2's pose 0 is 5 m north of R1's pose 0, facing the same way.
  ASSERT_TRUE(smoother.AddEncounter({kR1, 0}, {kR2, 0}, Pose2(0, 5, 0), odometry).ok());
  ASSERT_TRUE(smoother.Update().status.ok());
  // R2's key 2 folds onto R1's pose 1, 0.1 m ahead of it: in R2's frame, at (1.1, -5).
  ASSERT_TRUE(smoother.AddAlias({kR2, 2}, {kR1, 1}, Pose2(0.1, 0, 0), match).ok());
  ExpectNear(smoother.GlobalPose({kR2, 2}),
             Compose(smoother.GlobalPose({kR1, 1}), Pose2(0.1, 0, 0)), 1e-12);
  ExpectNear(smoother.FramePose({kR2, 2}), Pose2(1.1, -5, 0), 1e-6);
  // Its covariance in R2's frame: through R1's pose and both anchors, by one query.
  const Eigen::Matrix3d joint = smoother.JointCovariance({PoseKey{kR2, 2}});
  const Eigen::Matrix3d projected =
      smoother.ProjectedCovariance({PoseKey{kR2, 2}}, {Eigen::Matrix3d::Identity()});
  EXPECT_LT((joint - projected).cwiseAbs().maxCoeff(), 1e-12);
  EXPECT_GT(joint(1, 1), smoother.MarginalCovariance(PoseKey{kR1, 1})(1, 1));
  // R2's odometry 1 -> 2 is an encounter between R2's pose 1 and R1's pose 1.
  const int64_t factors = smoother.stats().factors;
  ASSERT_TRUE(smoother.AddBetween({kR2, 1}, {kR2, 2}, Pose2(0.1, -5, 0), odometry).ok());
  EXPECT_EQ(smoother.stats().factors, factors + 1);
  ASSERT_TRUE(smoother.Update().status.ok());
}

TEST_F(SmootherAliasTest, ANodeAfterAFoldOntoAnotherTrajectoryIsBorrowedFromIt) {
  ASSERT_TRUE(smoother.AddPose({kR2, 0}, Pose2()).ok());
  ASSERT_TRUE(smoother.AddEncounter({kR1, 0}, {kR2, 0}, Pose2(0, 5, 0), odometry).ok());
  ASSERT_TRUE(smoother.Update().status.ok());
  // R2's key 1 folds onto R1's pose 1; key 2, 1 m further, is a node: a pose of R1 (tied to
  // R1's pose 1 by a between factor), key 2 its alias at the identity.
  ASSERT_TRUE(smoother.AddAlias({kR2, 1}, {kR1, 1}, Pose2(0.1, 0, 0), match).ok());
  const PoseKey node = smoother.NextBorrowedNode(kR1);
  EXPECT_EQ(node, (PoseKey{kR1, kBorrowedNodeIndexBase}));
  ASSERT_TRUE(smoother.AddPose(node, Pose2(2.1, 0, 0)).ok());
  ASSERT_TRUE(smoother.AddAlias({kR2, 2}, node, Pose2(), Eigen::Matrix3d::Zero()).ok());
  const int64_t factors = smoother.stats().factors;
  ASSERT_TRUE(smoother.AddBetween({kR2, 1}, {kR2, 2}, Pose2(1, 0, 0), odometry).ok());
  EXPECT_EQ(smoother.stats().factors, factors + 1);
  const UpdateResult result = smoother.Update();
  ASSERT_TRUE(result.status.ok()) << result.status.message();
  EXPECT_TRUE(smoother.HasCovariance(node));
  EXPECT_NEAR(smoother.FramePose(node).x(), 2.1, 1e-6);
  ExpectNear(smoother.GlobalPose({kR2, 2}), smoother.GlobalPose(node), 1e-12);
  // Keys count where they belong: R1 keeps its two keyframes, R2 has three.
  EXPECT_EQ(smoother.NumPoses(kR1), 2);
  EXPECT_EQ(smoother.NumPoses(kR2), 3);
  EXPECT_EQ(smoother.NextBorrowedNode(kR1).index, kBorrowedNodeIndexBase + 1);
  ASSERT_EQ(smoother.GlobalTrajectory(kR1).size(), 2u);
}

TEST(PoseAliasesTest, FindsEveryAliasWhateverItsIndexAndKeepsPointersValid) {
  PoseAliases aliases;
  EXPECT_EQ(aliases.Find({kR1, 1}), nullptr);
  const auto alias_at = [](double x) {
    PoseAlias alias;
    alias.node = {kR1, 0};
    alias.T_node_key = Pose2(x, 0.0, 0.0);
    return alias;
  };
  // Keyframe indices in sequence (the array), with gaps (not aliases), one far beyond the
  // array (the map), one negative (an API caller's numbering) and one of another trajectory.
  aliases.Add({kR1, 1}, alias_at(1.0));
  const PoseAlias* first = aliases.Find({kR1, 1});
  ASSERT_NE(first, nullptr);
  for (int32_t i = 3; i < 3000; i += 2) aliases.Add({kR1, i}, alias_at(i));
  aliases.Add({kR1, 1 << 30}, alias_at(-1.0));
  aliases.Add({kR1, -5}, alias_at(-5.0));
  aliases.Add({kR2, 7}, alias_at(7.0));
  EXPECT_EQ(aliases.Find({kR1, 1}), first);  // still valid after 1500 more
  EXPECT_EQ(aliases.size(), 1503u);
  EXPECT_EQ(aliases.Count(kR1), 1502);
  EXPECT_EQ(aliases.Count(kR2), 1);
  for (int32_t i = 1; i < 3000; i += 2) {
    ASSERT_NE(aliases.Find({kR1, i}), nullptr) << i;
    EXPECT_EQ(aliases.Find({kR1, i})->T_node_key.x(), i);
    EXPECT_EQ(aliases.Find({kR1, i + 1}), nullptr) << i + 1;
  }
  EXPECT_EQ(aliases.Find({kR1, 1 << 30})->T_node_key.x(), -1.0);
  EXPECT_EQ(aliases.Find({kR1, -5})->T_node_key.x(), -5.0);
  EXPECT_EQ(aliases.Find({kR1, 3001}), nullptr);
  EXPECT_EQ(aliases.Find({kR2, 7})->T_node_key.x(), 7.0);
  EXPECT_EQ(aliases.Find({kR2, 1}), nullptr);
  EXPECT_EQ(aliases.Find({TrajectoryId(9), 1}), nullptr);
}

TEST(PoseAliasesTest, FoldedUnlessTheNodeWasBorrowedForTheKeyframe) {
  PoseAlias fold;
  fold.covariance = Diagonal(0.05, 0.01);
  EXPECT_TRUE(fold.folded());
  PoseAlias borrowed;
  borrowed.covariance.setZero();
  EXPECT_FALSE(borrowed.folded());
}

}  // namespace
}  // namespace anchormap
