#include "server/relative_pose.h"

#include <algorithm>
#include <cmath>
#include <optional>
#include <random>
#include <utility>
#include <vector>

#include <gtest/gtest.h>

#include "common/solver/smoother_options.h"

namespace anchormap {
namespace {

Eigen::Matrix3d Diagonal(double sx, double sy, double st) {
  return Eigen::Vector3d(sx * sx, sy * sy, st * st).asDiagonal();
}

// T_a2_a1 from T_a1_a2, with its covariance carried through the inverse's Jacobian (as
// PredictRelativePose gives it for the keys swapped).
PredictedRelativePose Inverted(const PredictedRelativePose& p) {
  Eigen::Matrix3d J;
  PredictedRelativePose out;
  out.T_a_b = Between(p.T_a_b, Pose2(), &J, nullptr);
  out.covariance = J * p.covariance * J.transpose();
  return out;
}

// The pair tested with c1 first, and with c2 first (the estimates between the keys reversed).
struct BothWays {
  double forward;
  double backward;
};
BothWays TestBothWays(const PredictedRelativePose& a1_a2, const Pose2& c1,
                      const Eigen::Matrix3d& C1, const PredictedRelativePose& b1_b2,
                      const Pose2& c2, const Eigen::Matrix3d& C2) {
  return {PairwiseInconsistency2(a1_a2, c1, C1, b1_b2, c2, C2),
          PairwiseInconsistency2(Inverted(a1_a2), c2, C2, Inverted(b1_b2), c1, C1)};
}

// The pairwise value logged 6.59 one way and 2.21 the other for one true pair of ACES 3
// robots (R3 keyframes 110 and 120 against R2's 65 and 75; aces-safety.md) was computed at
// two times: when the second candidate came (282.4 s) and when the pair was qualified to
// join (309.8 s). In between the estimate of R3 110 -> 120 moved (0.05 m, 0.013 rad) and its
// heading sigma shrank (0.0052 -> 0.0036 rad). With the logged values (diagonal
// covariances, as logged), each time gives one value both ways; the two times differ.
// Pose i of trajectory r: the first at its frame's origin, each later one placed by the
// odometry step z from pose i - 1, with a between factor of that covariance.
void AddOdometryPose(Smoother* smoother, int r, int i, const Pose2& z,
                     const Eigen::Matrix3d& covariance) {
  const PoseKey key{TrajectoryId(r), i};
  if (i == 0) {
    ASSERT_TRUE(smoother->AddPose(key, Pose2()).ok());
    return;
  }
  const PoseKey previous{TrajectoryId(r), i - 1};
  ASSERT_TRUE(smoother->AddPose(key, Compose(smoother->FramePose(previous), z)).ok());
  ASSERT_TRUE(smoother->AddBetween(previous, key, z, covariance).ok());
}

TEST(PairwiseInconsistencyTest, TheLoggedAcesPairDiffersByTimeNotByOrder) {
  const Pose2 c1(4.14, 0.09, 2.884), c2(2.35, 0.24, -0.253);
  const Eigen::Matrix3d C1 = Diagonal(0.020, 0.029, 0.0052);
  const Eigen::Matrix3d C2 = Diagonal(0.020, 0.023, 0.0050);
  // At 282.4 s, logged from c1 (110-65) to c2 (120-75).
  const PredictedRelativePose a_early{Pose2(3.75, -0.18, -1.559), Diagonal(0.012, 0.014, 0.0052)};
  const PredictedRelativePose b_early{Pose2(-0.57, 2.51, 1.612), Diagonal(0.013, 0.016, 0.0036)};
  const BothWays early = TestBothWays(a_early, c1, C1, b_early, c2, C2);
  // At 309.8 s, logged from c2 to c1.
  const PredictedRelativePose a_late{Pose2(-0.27, -3.74, 1.546), Diagonal(0.013, 0.012, 0.0036)};
  const PredictedRelativePose b_late{Pose2(-2.53, -0.47, -1.612), Diagonal(0.015, 0.017, 0.0036)};
  const BothWays late = TestBothWays(Inverted(a_late), c1, C1, Inverted(b_late), c2, C2);
  EXPECT_NEAR(early.forward, 7.79, 0.01);
  EXPECT_NEAR(late.forward, 2.38, 0.01);
  EXPECT_NEAR(early.backward, early.forward, 1e-3 * early.forward);
  EXPECT_NEAR(late.backward, late.forward, 1e-3 * late.forward);
}

// Random pairs: exactly consistent ones score 0 both ways; noisy ones (c2 drawn from its
// covariance) score the same both ways to first order: the two orders linearise at the two
// ends of the loop, so they differ by a fraction that shrinks with the residual (measured:
// at most 0.74 % at one sigma, 0.073 % at a tenth of it, over 300 pairs).
double WorstRelativeDifference(double noise_scale) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> position(-5.0, 5.0), angle(-M_PI, M_PI),
      sigma_m(0.005, 0.05), sigma_rad(0.002, 0.01);
  std::normal_distribution<double> unit(0.0, 1.0);
  auto random_pose = [&] {
    const double x = position(rng);
    const double y = position(rng);
    return Pose2(x, y, angle(rng));
  };
  auto random_covariance = [&] {
    const double sx = sigma_m(rng);
    const double sy = sigma_m(rng);
    const double st = sigma_rad(rng);
    return Diagonal(sx, sy, st);
  };
  double worst = 0.0;
  for (int trial = 0; trial < 300; ++trial) {
    const PredictedRelativePose a{random_pose(), random_covariance()};
    const PredictedRelativePose b{random_pose(), random_covariance()};
    const Pose2 c1 = random_pose();
    const Eigen::Matrix3d C1 = random_covariance(), C2 = random_covariance();
    // c2 as the loop predicts it: T_a2_b2 = T_a2_a1 (+) c1 (+) T_b1_b2.
    const Pose2 c2_exact = Compose(a.T_a_b.Inverse(), Compose(c1, b.T_a_b));
    const BothWays exact = TestBothWays(a, c1, C1, b, c2_exact, C2);
    EXPECT_NEAR(exact.forward, 0.0, 1e-9);
    EXPECT_NEAR(exact.backward, 0.0, 1e-9);
    const double zx = unit(rng);
    const double zy = unit(rng);
    const double zt = unit(rng);
    const Eigen::Vector3d noise =
        noise_scale * C2.diagonal().cwiseSqrt().cwiseProduct(Eigen::Vector3d(zx, zy, zt));
    const Pose2 c2 = Pose2::FromVector(c2_exact.vector() + noise);
    const BothWays noisy = TestBothWays(a, c1, C1, b, c2, C2);
    EXPECT_GT(noisy.forward, 0.0);
    worst = std::max(worst, std::abs(noisy.backward - noisy.forward) / noisy.forward);
  }
  return worst;
}

TEST(PairwiseInconsistencyTest, OneValueBothWaysToFirstOrder) {
  const double at_one_sigma = WorstRelativeDifference(1.0);
  const double at_a_tenth = WorstRelativeDifference(0.1);
  EXPECT_LT(at_one_sigma, 0.02);
  EXPECT_LT(at_a_tenth, 0.002);
  EXPECT_LT(at_a_tenth, 0.2 * at_one_sigma);  // shrinks with the residual
}

// Four robots on noisy odometry meet every few poses: pairs (0, 1) and (2, 3) form two
// groups that then merge (a partial step, in the server's configuration). After every update, the
// predicted covariance of poses in one trajectory and across anchored trajectories (one sparse
// solve, Smoother::ProjectedCovariance) equals J Sigma J^T built from the joint covariance blocks.
TEST(PredictRelativePoseTest, CovarianceEqualsTheJointCovarianceProjectedAfterEveryUpdate) {
  constexpr int kRobots = 4, kPoses = 40;
  const int meetings[4][2] = {{0, 1}, {2, 3}, {1, 2}, {3, 0}};
  Smoother smoother(ServerModeOptions());
  std::mt19937 rng(17);
  std::normal_distribution<double> noise(0.0, 0.02);
  const Eigen::Matrix3d odometry_covariance = Diagonal(0.02, 0.02, 0.02);
  auto truth = [](int r, int i) {
    const double angle = 0.15 * i + 2.0 * r;
    return Pose2(4.0 * std::cos(angle) + r, 4.0 * std::sin(angle), angle + M_PI / 2);
  };
  double worst = 0.0;
  int compared_across = 0, compared_within = 0;
  for (int i = 0; i < kPoses; ++i) {
    for (int r = 0; r < kRobots; ++r) {
      Pose2 z;
      if (i > 0) {
        z = Between(truth(r, i - 1), truth(r, i));
        z = Pose2(z.x() + noise(rng), z.y() + noise(rng), z.theta() + noise(rng));
      }
      AddOdometryPose(&smoother, r, i, z, odometry_covariance);
    }
    if (i >= 4 && i % 3 == 1) {
      const int a = meetings[(i - 4) / 3 % 4][0], b = meetings[(i - 4) / 3 % 4][1], j = i - 2;
      ASSERT_TRUE(smoother
                      .AddEncounter({TrajectoryId(a), i}, {TrajectoryId(b), j},
                                    Between(truth(a, i), truth(b, j)), Diagonal(0.05, 0.05, 0.02))
                      .ok());
    }
    ASSERT_TRUE(smoother.Update().status.ok());
    // Every pair at once first (side by side): each the single prediction's bits below.
    std::vector<std::pair<PoseKey, PoseKey>> pairs;
    for (int r = 0; r < kRobots; ++r) {
      for (int s = 0; s < kRobots; ++s)
        pairs.push_back({{TrajectoryId(r), i / 3}, {TrajectoryId(s), i}});
    }
    const std::vector<std::optional<PredictedRelativePose>> together =
        PredictRelativePoses(&smoother, pairs);
    ASSERT_EQ(together.size(), pairs.size());
    for (int r = 0; r < kRobots; ++r) {
      for (int s = 0; s < kRobots; ++s) {
        const PoseKey a{TrajectoryId(r), i / 3}, b{TrajectoryId(s), i};
        const std::optional<PredictedRelativePose> predicted = PredictRelativePose(&smoother, a, b);
        const std::optional<PredictedRelativePose>& side_by_side = together[r * kRobots + s];
        ASSERT_EQ(side_by_side.has_value(), predicted.has_value());
        if (!predicted) continue;
        EXPECT_EQ(side_by_side->covariance, predicted->covariance);
        EXPECT_EQ(side_by_side->T_a_b.x(), predicted->T_a_b.x());
        EXPECT_EQ(side_by_side->T_a_b.theta(), predicted->T_a_b.theta());
        Eigen::Matrix3d expected;
        if (r == s) {
          Eigen::Matrix3d J_a, J_b;
          Between(smoother.FramePose(a), smoother.FramePose(b), &J_a, &J_b);
          Eigen::Matrix<double, 3, 6> J;
          J << J_a, J_b;
          expected = J * smoother.JointCovariance({a, b}) * J.transpose();
          ++compared_within;
        } else {
          const AnchorKey A{a.trajectory}, B{b.trajectory};
          Eigen::Matrix3d dga_dA, dga_dx, dgb_dB, dgb_dx, dh_dga, dh_dgb;
          const Pose2 ga = Compose(smoother.Value(A), smoother.FramePose(a), &dga_dA, &dga_dx);
          const Pose2 gb = Compose(smoother.Value(B), smoother.FramePose(b), &dgb_dB, &dgb_dx);
          Between(ga, gb, &dh_dga, &dh_dgb);
          Eigen::Matrix<double, 3, 12> J;
          J << dh_dga * dga_dx, dh_dgb * dgb_dx, dh_dga * dga_dA, dh_dgb * dgb_dB;
          expected = J * smoother.JointCovariance({a, b, A, B}) * J.transpose();
          ++compared_across;
        }
        worst = std::max(worst, (predicted->covariance - expected).cwiseAbs().maxCoeff() /
                                    expected.cwiseAbs().maxCoeff());
        EXPECT_FALSE(predicted->partial);
        // A solve never stopped gives the plain prediction's bits; so does one that could
        // stop at once, as R has not changed since the plain one: the memo answers, exact.
        // (Stopped solves: CovarianceProjectionTest.StoppedSolvesGiveLowerBounds...)
        const auto never = [](const Pose2&, const Eigen::Matrix3d&) { return false; };
        const auto at_once = [](const Pose2&, const Eigen::Matrix3d&) { return true; };
        for (const EnoughCovariance& enough :
             {EnoughCovariance(never), EnoughCovariance(at_once)}) {
          const std::optional<PredictedRelativePose> again =
              PredictRelativePose(&smoother, a, b, enough);
          ASSERT_TRUE(again);
          EXPECT_FALSE(again->partial);
          EXPECT_EQ(again->covariance, predicted->covariance);
          EXPECT_EQ(again->T_a_b.x(), predicted->T_a_b.x());
          EXPECT_EQ(again->T_a_b.theta(), predicted->T_a_b.theta());
        }
      }
    }
  }
  EXPECT_GT(compared_within, 100);
  EXPECT_GT(compared_across, 100);
  EXPECT_LT(worst, 1e-10);
  EXPECT_GT(smoother.stats().partial_merges, 0);
}

// Between updates (MappingServerOptions::solve_period_s) a merge joins two groups in the
// smoother's bookkeeping at once, while R still holds them apart, each with its own gauge:
// a prediction across them then would read a covariance of a graph that no longer exists.
// It waits for the update; so does one involving a pose or anchor not yet in R.
TEST(PredictRelativePoseTest, NothingIsPredictedFromAGraphChangeNotYetSolved) {
  constexpr int kRobots = 4, kPoses = 8;
  Smoother smoother(ServerModeOptions());
  const Eigen::Matrix3d odometry_covariance = Diagonal(0.02, 0.02, 0.02);
  const Pose2 step(1.0, 0.0, 0.1);
  for (int r = 0; r < kRobots; ++r) {
    for (int i = 0; i < kPoses; ++i) AddOdometryPose(&smoother, r, i, step, odometry_covariance);
  }
  const Eigen::Matrix3d encounter_covariance = Diagonal(0.05, 0.05, 0.02);
  ASSERT_TRUE(smoother
                  .AddEncounter({TrajectoryId(0), 3}, {TrajectoryId(1), 3}, Pose2(0, 2, 0),
                                encounter_covariance)
                  .ok());
  ASSERT_TRUE(smoother
                  .AddEncounter({TrajectoryId(2), 3}, {TrajectoryId(3), 3}, Pose2(0, 2, 0),
                                encounter_covariance)
                  .ok());
  // New anchors, not yet in R.
  EXPECT_TRUE(smoother.GroupChangePending());
  EXPECT_FALSE(PredictRelativePose(&smoother, {TrajectoryId(0), 5}, {TrajectoryId(1), 5}));
  ASSERT_TRUE(smoother.Update().status.ok());
  EXPECT_FALSE(smoother.GroupChangePending());
  EXPECT_FALSE(smoother.HasPendingChanges());
  ASSERT_TRUE(PredictRelativePose(&smoother, {TrajectoryId(0), 5}, {TrajectoryId(1), 5}));
  EXPECT_FALSE(PredictRelativePose(&smoother, {TrajectoryId(0), 5}, {TrajectoryId(3), 5}));

  // The merge of {0, 1} and {2, 3}: one frame in the bookkeeping, two in R.
  ASSERT_TRUE(smoother
                  .AddEncounter({TrajectoryId(1), 6}, {TrajectoryId(2), 6}, Pose2(0, 2, 0),
                                encounter_covariance)
                  .ok());
  EXPECT_TRUE(InOneFrame(smoother, TrajectoryId(0), TrajectoryId(3)));
  EXPECT_TRUE(smoother.HasCovariance(PoseKey{TrajectoryId(0), 5}));
  EXPECT_TRUE(smoother.GroupChangePending());
  EXPECT_TRUE(smoother.HasPendingChanges());
  EXPECT_FALSE(smoother.IsSolved(PoseKey{TrajectoryId(0), 5}));
  EXPECT_FALSE(PredictRelativePose(&smoother, {TrajectoryId(0), 5}, {TrajectoryId(3), 5}));
  EXPECT_FALSE(PredictRelativePose(&smoother, {TrajectoryId(0), 5}, {TrajectoryId(1), 5}));
  ASSERT_TRUE(smoother.Update().status.ok());
  EXPECT_TRUE(smoother.IsSolved(PoseKey{TrajectoryId(0), 5}));
  const std::optional<PredictedRelativePose> across =
      PredictRelativePose(&smoother, {TrajectoryId(0), 5}, {TrajectoryId(3), 5});
  ASSERT_TRUE(across);
  // Now the chain through both encounters: looser than either encounter alone.
  EXPECT_GT(across->covariance(0, 0), encounter_covariance(0, 0));

  // A pose added since the update has no covariance yet; the others keep theirs (only a
  // group change makes every cross-frame covariance stale).
  const PoseKey late{TrajectoryId(0), kPoses};
  ASSERT_TRUE(
      smoother.AddPose(late, Compose(smoother.FramePose({TrajectoryId(0), kPoses - 1}), step))
          .ok());
  ASSERT_TRUE(
      smoother.AddBetween({TrajectoryId(0), kPoses - 1}, late, step, odometry_covariance).ok());
  EXPECT_TRUE(smoother.HasPendingChanges());
  EXPECT_FALSE(smoother.GroupChangePending());
  EXPECT_FALSE(PredictRelativePose(&smoother, late, {TrajectoryId(3), 5}));
  EXPECT_TRUE(PredictRelativePose(&smoother, {TrajectoryId(0), 5}, {TrajectoryId(3), 5}));
}

}  // namespace
}  // namespace anchormap
