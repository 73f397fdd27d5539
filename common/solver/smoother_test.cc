#include "common/solver/smoother.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <random>
#include <string>
#include <utility>
#include <vector>

#include <gtest/gtest.h>

#include "common/solver/ordering.h"
#include "tests/testing/dense_oracle.h"
#include "tests/testing/graph_replay.h"
#include "tests/testing/random_graph.h"

namespace anchormap {
namespace {

using testing::DenseOracle;
using testing::Values;

const Eigen::Matrix3d kCovariance = Eigen::Vector3d(0.01, 0.01, 0.001).asDiagonal();

// Adds pose i of `graph` as (t, i), placed by odometry from the estimate of pose i - 1, and
// every edge of `graph` that ends at i.
::testing::AssertionResult AddPoseAndItsEdges(Smoother* smoother, const PoseGraph& graph,
                                              TrajectoryId t, int i) {
  const Pose2 initial =
      i == 0 ? Pose2()
             : Compose(smoother->FramePose({t, i - 1}), graph.edges[i - 1].measured_T_from_to);
  if (!smoother->AddPose({t, i}, initial).ok())
    return ::testing::AssertionFailure() << "pose " << i;
  for (const GraphEdge& e : graph.edges) {
    if (e.to != i) continue;
    if (!smoother
             ->AddBetween({t, static_cast<int32_t>(e.from)}, {t, i}, e.measured_T_from_to,
                          e.information.inverse())
             .ok()) {
      return ::testing::AssertionFailure() << "edge " << e.from << " -> " << i;
    }
  }
  return ::testing::AssertionSuccess();
}

// Adds a random single-trajectory graph as trajectory `t` and returns its ground truth.
PoseGraph AddRandomTrajectory(Smoother* smoother, TrajectoryId t, int poses, uint32_t seed,
                              bool update_each_step) {
  testing::RandomGraphOptions options;
  options.poses = poses;
  options.loop_closures = poses / 5;
  options.seed = seed;
  const PoseGraph graph = testing::RandomGraph(options);
  for (int i = 0; i < poses; ++i) {
    Pose2 initial;
    if (i > 0)
      initial = Compose(smoother->FramePose({t, i - 1}), graph.edges[i - 1].measured_T_from_to);
    EXPECT_TRUE(smoother->AddPose({t, i}, initial).ok());
    if (i > 0) {
      EXPECT_TRUE(smoother
                      ->AddBetween({t, i - 1}, {t, i}, graph.edges[i - 1].measured_T_from_to,
                                   graph.edges[i - 1].information.inverse())
                      .ok());
    }
    for (size_t e = poses - 1; e < graph.edges.size(); ++e) {
      if (graph.edges[e].to == i) {
        EXPECT_TRUE(smoother
                        ->AddBetween({t, static_cast<int32_t>(graph.edges[e].from)}, {t, i},
                                     graph.edges[e].measured_T_from_to,
                                     graph.edges[e].information.inverse())
                        .ok());
      }
    }
    if (update_each_step) {
      EXPECT_TRUE(smoother->Update().status.ok());
    }
  }
  return graph;
}

Values CurrentValues(const Smoother& smoother) {
  Values values;
  for (const Factor& f : smoother.ActiveFactors()) {
    for (const Key& key : FactorKeys(f)) values[key] = smoother.Value(key);
  }
  return values;
}

// Adds random graph `g`'s poses to `smoother` one update at a time (trajectory 0) and
// returns the worst relative excess of an update's chi2 over the dense optimum of the factors
// so far (from the third pose on).
double WorstExcessOverTheOptimum(Smoother* smoother, const testing::RandomGraphOptions& g) {
  const PoseGraph graph = testing::RandomGraph(g);
  const TrajectoryId t(0);
  double worst_excess = 0.0;
  for (int i = 0; i < g.poses; ++i) {
    EXPECT_TRUE(AddPoseAndItsEdges(smoother, graph, t, i));
    EXPECT_TRUE(smoother->Update().status.ok());
    if (i < 2) continue;
    const DenseOracle oracle(smoother->ActiveFactors());
    const double optimum = oracle.Chi2(oracle.Solve(CurrentValues(*smoother), 1e-10, 20));
    worst_excess = std::max(worst_excess, (smoother->Chi2() - optimum) / optimum);
  }
  return worst_excess;
}

TEST(SmootherTest, RejectsBadInputWithReasons) {
  Smoother smoother;
  EXPECT_EQ(smoother.AddPose({TrajectoryId(0), 1}, Pose2()).message(),
            "trajectory 0 must start with pose index 0");
  ASSERT_TRUE(smoother.AddPose({TrajectoryId(0), 0}, Pose2()).ok());
  EXPECT_EQ(smoother.AddPose({TrajectoryId(0), 0}, Pose2()).message(),
            "pose pose(0,0) exists already");
  EXPECT_EQ(smoother.AddPose({TrajectoryId(0), 1}, Pose2(std::nan(""), 0, 0)).message(),
            "initial pose is not finite");
  ASSERT_TRUE(smoother.AddPose({TrajectoryId(0), 1}, Pose2()).ok());
  Eigen::Matrix3d bad = kCovariance;
  bad(2, 2) = -1;
  EXPECT_EQ(smoother.AddBetween({TrajectoryId(0), 0}, {TrajectoryId(0), 1}, Pose2(), bad).message(),
            "covariance rejected: matrix is not positive definite");
  EXPECT_EQ(smoother.AddBetween({TrajectoryId(0), 0}, {TrajectoryId(0), 7}, Pose2(), kCovariance)
                .message(),
            "between factor on an unknown pose");
  EXPECT_EQ(smoother.AddEncounter({TrajectoryId(0), 0}, {TrajectoryId(0), 1}, Pose2(), kCovariance)
                .message(),
            "encounter within one trajectory: use AddBetween (a loop closure)");
  EXPECT_EQ(smoother
                .AddBetween({TrajectoryId(0), 0}, {TrajectoryId(0), 1}, Pose2(1, std::nan(""), 0),
                            kCovariance)
                .message(),
            "measurement is not finite");
}

TEST(SmootherTest, UnconstrainedPoseWaitsInsteadOfBreakingTheSolution) {
  Smoother smoother;
  ASSERT_TRUE(smoother.AddPose({TrajectoryId(0), 0}, Pose2()).ok());
  ASSERT_TRUE(smoother.AddPose({TrajectoryId(0), 1}, Pose2(1, 0, 0)).ok());
  ASSERT_TRUE(smoother.AddPose({TrajectoryId(0), 2}, Pose2(2, 0, 0)).ok());
  ASSERT_TRUE(
      smoother.AddBetween({TrajectoryId(0), 1}, {TrajectoryId(0), 2}, Pose2(1, 0, 0), kCovariance)
          .ok());
  const UpdateResult result = smoother.Update();
  EXPECT_FALSE(result.status.ok());  // poses 1 and 2 are not tied to pose 0 yet
  EXPECT_NE(result.status.message().find("wait for measurements"), std::string::npos);
  EXPECT_TRUE(smoother.FramePose({TrajectoryId(0), 0}).IsFinite());
  ASSERT_TRUE(
      smoother.AddBetween({TrajectoryId(0), 0}, {TrajectoryId(0), 1}, Pose2(1, 0, 0.1), kCovariance)
          .ok());
  EXPECT_TRUE(smoother.Update().status.ok());
  // One linear step from the initial guess, then the nonlinear optimum.
  EXPECT_NEAR(smoother.FramePose({TrajectoryId(0), 2}).y(), 0.1, 1e-9);
  EXPECT_TRUE(smoother.BatchOptimize().status.ok());
  EXPECT_NEAR(smoother.FramePose({TrajectoryId(0), 2}).y(), std::sin(0.1), 1e-9);
}

TEST(SmootherTest, IncrementalMatchesDenseSolveAfterFinalBatch) {
  for (NonlinearMethod method : {NonlinearMethod::kGaussNewton, NonlinearMethod::kDogLeg}) {
    for (double threshold : {0.0, 1e-3}) {
      SmootherOptions options;
      options.method = method;
      options.batch_every_updates = 7;
      options.backsubstitution_threshold = threshold;
      Smoother smoother(options);
      AddRandomTrajectory(&smoother, TrajectoryId(0), 60, 4, /*update_each_step=*/true);
      ASSERT_TRUE(smoother.BatchOptimize().status.ok());
      const DenseOracle oracle(smoother.ActiveFactors());
      const Values optimum = oracle.Solve(CurrentValues(smoother));
      for (const auto& [key, value] : optimum) {
        EXPECT_LT(PoseError(smoother.Value(key), value).cwiseAbs().maxCoeff(), 1e-6)
            << key.ToString();
      }
      EXPECT_NEAR(smoother.Chi2(), oracle.Chi2(optimum), 1e-6 * oracle.Chi2(optimum));
    }
  }
}

// Seeded call sequences of the server's configuration in which some poses come with no
// odometry edge, tied only by an encounter (they wait while that encounter cannot determine
// them), with group merges and the batch steps they bring. A batch step can leave out of R a
// variable that was in it (after a merge its factors no longer ground it); it must wait
// again and enter R once determined. Before the fix it stayed grounded with no position and
// the next Givens update indexed R at -1 (heap corruption; found by rpg24's 100-robot replay
// with --reduced-graph, reproduced here). At the end every pose is tied to its predecessor
// and every trajectory joined: the estimate is at the dense optimum.
TEST(SmootherTest, VariablesABatchStepLeavesOutOfRWaitAgainAndReachTheOptimum) {
  for (int seed = 0; seed < 40; ++seed) {  // seed 25 met the bug
    SCOPED_TRACE("seed " + std::to_string(seed));
    std::mt19937 rng(static_cast<unsigned>(seed));
    auto uniform = [&](double a, double b) {
      return std::uniform_real_distribution<double>(a, b)(rng);
    };
    auto pick = [&](int n) { return std::uniform_int_distribution<int>(0, n - 1)(rng); };
    Smoother smoother(ServerModeWithCorrectionOptions());
    const int num_trajectories = 3 + pick(5);
    std::vector<std::vector<Pose2>> truth(static_cast<size_t>(num_trajectories));
    std::vector<Pose2> origin;
    for (int t = 0; t < num_trajectories; ++t) {
      origin.emplace_back(uniform(-20, 20), uniform(-20, 20), uniform(-3, 3));
    }
    std::vector<std::pair<int, int32_t>> untied;  // poses added without their odometry edge
    auto key = [](int t, int i) { return PoseKey{TrajectoryId(t + 1), static_cast<int32_t>(i)}; };
    auto add_pose = [&](int t, bool tied) {
      std::vector<Pose2>& poses = truth[static_cast<size_t>(t)];
      const int i = static_cast<int>(poses.size());
      poses.push_back(i == 0 ? Pose2()
                             : Compose(poses.back(), Pose2(uniform(0.2, 1.0), uniform(-0.1, 0.1),
                                                           uniform(-0.3, 0.3))));
      ASSERT_TRUE(smoother.AddPose(key(t, i), poses.back()).ok());
      if (i == 0) return;
      if (!tied) {
        untied.emplace_back(t, i);
        return;
      }
      ASSERT_TRUE(
          smoother
              .AddBetween(key(t, i - 1), key(t, i), Between(poses[i - 1], poses[i]), kCovariance)
              .ok());
    };
    auto encounter = [&](int a, int ia, int b, int ib) {
      const Pose2 global_a = Compose(origin[a], truth[a][ia]);
      const Pose2 global_b = Compose(origin[b], truth[b][ib]);
      ASSERT_TRUE(
          smoother.AddEncounter(key(a, ia), key(b, ib), Between(global_a, global_b), kCovariance)
              .ok());
    };
    auto newest = [&](int t) { return static_cast<int>(truth[t].size()) - 1; };
    for (int t = 0; t < num_trajectories; ++t) add_pose(t, true);
    const int steps = 30 + pick(60);
    for (int k = 0; k < steps; ++k) {
      const int op = pick(10);
      const int t = pick(num_trajectories);
      const int u = (t + 1 + pick(num_trajectories - 1)) % num_trajectories;  // != t
      if (op < 5) {
        add_pose(t, true);
      } else if (op < 7) {
        add_pose(t, false);
        encounter(u, pick(newest(u) + 1), t, newest(t));
      } else {
        encounter(t, pick(newest(t) + 1), u, pick(newest(u) + 1));
      }
      if (pick(3) == 0) smoother.Update();  // waiting variables: status not ok, by design
    }
    // Everything determined: the odometry edges left out, and a chain of encounters.
    for (const auto& [t, i] : untied) {
      ASSERT_TRUE(smoother
                      .AddBetween(key(t, i - 1), key(t, i), Between(truth[t][i - 1], truth[t][i]),
                                  kCovariance)
                      .ok());
    }
    for (int t = 1; t < num_trajectories; ++t) encounter(t - 1, 0, t, 0);
    const UpdateResult last = smoother.Update();
    ASSERT_TRUE(last.status.ok()) << last.status.message();
    for (int t = 0; t < num_trajectories; ++t) {
      for (int i = 0; i <= newest(t); ++i) ASSERT_TRUE(smoother.HasCovariance(key(t, i)));
    }
    ASSERT_TRUE(smoother.BatchOptimize().status.ok());
    const DenseOracle oracle(smoother.ActiveFactors());
    const Values optimum = oracle.Solve(CurrentValues(smoother));
    for (const auto& [k, value] : optimum) {
      EXPECT_LT(PoseError(smoother.Value(k), value).cwiseAbs().maxCoeff(), 1e-6) << k.ToString();
    }
  }
}

TEST(SmootherTest, BatchStepStopsOnTheDecreaseItPredictsWithinThatOfTheOptimum) {
  // convergence_decrease: a batch step from odometry alone (loop closures far off) stops
  // once the decrease of chi2 its step predicts is below 1e-6 x chi2. Against the step
  // criterion alone (1e-12: to rounding) it takes fewer iterations, and its chi2 stays
  // within 1e-6 of the dense optimum's (measured: see the printed figures).
  auto run = [](double decrease, double* excess) {
    SmootherOptions options;
    options.batch_every_updates = 0;
    options.convergence_step = 1e-12;
    options.convergence_decrease = decrease;
    Smoother smoother(options);
    testing::RandomGraphOptions g;
    g.poses = 80;
    g.loop_closures = 30;
    g.seed = 5;
    g.sigma_theta_rad = 0.05;  // odometry drift the first iterations must undo
    const PoseGraph graph = testing::RandomGraph(g);
    for (int i = 0; i < g.poses; ++i) {
      EXPECT_TRUE(AddPoseAndItsEdges(&smoother, graph, TrajectoryId(0), i));
    }
    EXPECT_TRUE(smoother.BatchOptimize().status.ok());
    const DenseOracle oracle(smoother.ActiveFactors());
    const double optimum = oracle.Chi2(oracle.Solve(CurrentValues(smoother), 1e-14, 50));
    *excess = (smoother.Chi2() - optimum) / optimum;
    std::printf("convergence_decrease %g: %lld iterations, chi2 excess %.3g\n", decrease,
                static_cast<long long>(smoother.stats().batch_iterations), *excess);
    return smoother.stats().batch_iterations;
  };
  double excess_off = 0.0, excess_on = 0.0;
  const int64_t iterations_off = run(0.0, &excess_off);
  const int64_t iterations_on = run(1e-6, &excess_on);
  EXPECT_LT(iterations_on, iterations_off);
  EXPECT_LE(std::abs(excess_off), 1e-12);
  EXPECT_LE(excess_on, 1e-6);
  EXPECT_GE(excess_on, -1e-12);
}

// The 100-pose graph both far-off batch-step tests start from (odometry with heading noise
// 0.3 rad): a converging batch step from there ends at the optimum (115.277818, as a dense
// solve from the result) within 25 iterations.
void ExpectFarOffBatchStepReachesTheOptimum(const SmootherOptions& options) {
  Smoother smoother(options);
  testing::RandomGraphOptions g;
  g.poses = 100;
  g.loop_closures = 40;
  g.seed = 4;
  g.sigma_theta_rad = 0.3;
  const PoseGraph graph = testing::RandomGraph(g);
  for (int i = 0; i < g.poses; ++i) {
    ASSERT_TRUE(AddPoseAndItsEdges(&smoother, graph, TrajectoryId(0), i));
  }
  ASSERT_TRUE(smoother.BatchOptimize().status.ok());
  EXPECT_LE(smoother.stats().batch_iterations, 25);
  const DenseOracle oracle(smoother.ActiveFactors());
  const double optimum = oracle.Chi2(oracle.Solve(CurrentValues(smoother), 1e-14, 50));
  EXPECT_NEAR(smoother.Chi2(), optimum, 1e-9 * optimum);
  EXPECT_NEAR(optimum, 115.277818, 1e-5);
}

TEST(SmootherTest, BatchStepFromFarOffShortensStepsThatOvershootAndReachesTheOptimum) {
  // Gauss-Newton from odometry with heading noise 0.3 rad: full steps overshoot (chi2
  // rises); a step that rose by more than it predicted to fall is halved until chi2 does
  // not rise. Measured on this graph: 18 iterations instead of 38 with full steps, the
  // same optimum (115.277818, as a dense solve from the result).
  SmootherOptions options;
  options.batch_every_updates = 0;
  ExpectFarOffBatchStepReachesTheOptimum(options);
}

TEST(SmootherTest, OneIterationBatchStepThatWouldRaiseChi2IsShortenedWhenTheEstimateIsKept) {
  // A fill or periodic batch step relinearises once. Its one Gauss-Newton step from
  // odometry with heading noise 0.3 rad raises chi2 on this graph (measured 26799 -> 87842);
  // taken whole, the correction had to repair it (at 100 robots a weakly held anchor's step
  // of metres: chi2 15207 -> 97190). In the kept-estimate (CG) mode the correction holds
  // what the estimate does not take of the step, halved until chi2 does not rise. A
  // tolerance that ends every correction at entry shows the batch step's own estimate; the
  // library's default mode still takes the step whole.
  testing::RandomGraphOptions g;
  g.poses = 30;
  g.loop_closures = 12;
  g.seed = 2;
  g.sigma_theta_rad = 0.3;
  const PoseGraph graph = testing::RandomGraph(g);
  auto run = [&](SmootherOptions options, double* chi2_before) {
    options.batch_every_updates = 1;
    Smoother smoother(options);
    for (int i = 0; i < g.poses; ++i) {
      EXPECT_TRUE(AddPoseAndItsEdges(&smoother, graph, TrajectoryId(0), i));
    }
    *chi2_before = smoother.Chi2();
    const UpdateResult result = smoother.Update();
    EXPECT_TRUE(result.status.ok());
    EXPECT_TRUE(result.batch_step);
    EXPECT_EQ(result.iterations, 1);
    return smoother.Chi2();
  };
  SmootherOptions kept = ServerModeWithCorrectionOptions();
  kept.correction_tolerance = 1e9;
  kept.relinearize_when_correction_stalls = false;
  double before_kept = 0.0, before_whole = 0.0;
  const double after_kept = run(kept, &before_kept);
  const double after_whole = run(SmootherOptions(), &before_whole);
  std::printf("chi2 %.6g before, %.6g after the whole step, %.6g after the shortened one\n",
              before_whole, after_whole, after_kept);
  EXPECT_EQ(before_kept, before_whole);
  EXPECT_GT(after_whole, before_whole);
  EXPECT_LE(after_kept, before_kept);
}

TEST(SmootherTest, BatchStepFromFarOffReachesTheOptimumWhenTheEstimateIsKept) {
  // The converging batch step in the kept-estimate mode: overshooting steps are halved in
  // place as in the default mode, and the step ends early only when a halved step buys
  // less than the correction's tolerance; from far off that never happens before the
  // optimum (the graph of the test above).
  SmootherOptions options = ServerModeWithCorrectionOptions();
  options.correction_tolerance = 1e-4;
  ExpectFarOffBatchStepReachesTheOptimum(options);
}

TEST(SmootherTest, ConjugateGradientCorrectionReachesTheDenseOptimumAfterEveryUpdate) {
  // No batch step, no relinearisation: R stays linearised where its rows were added
  // (stale after each loop closure) and serves only as the preconditioner; the
  // correction's Gauss-Newton steps by conjugate gradients (run to rounding: a tolerance
  // below what rounding lets it reach) must still reach the optimum of the nonlinear
  // problem after every update, as a dense solve does (measured worst 9.2e-11).
  SmootherOptions options;
  options.batch_every_updates = 0;
  options.batch_when_fill_grows = 0;
  options.correction_tolerance = 1e-20;
  options.correction_iterations = 20;
  options.correction_cg_iterations = 2000;
  Smoother smoother(options);
  testing::RandomGraphOptions g;
  g.poses = 40;
  g.loop_closures = 10;
  g.seed = 7;
  const PoseGraph graph = testing::RandomGraph(g);
  const TrajectoryId t(0);
  double worst_error = 0.0;
  int checked = 0;
  for (int i = 0; i < g.poses; ++i) {
    ASSERT_TRUE(AddPoseAndItsEdges(&smoother, graph, t, i));
    ASSERT_TRUE(smoother.Update().status.ok());
    if (i < 2) continue;
    const DenseOracle oracle(smoother.ActiveFactors());
    const Values optimum = oracle.Solve(CurrentValues(smoother), 1e-14, 50);
    for (const auto& [key, value] : optimum) {
      worst_error =
          std::max(worst_error, PoseError(smoother.Value(key), value).cwiseAbs().maxCoeff());
    }
    EXPECT_NEAR(smoother.Chi2(), oracle.Chi2(optimum), 1e-9 * oracle.Chi2(optimum) + 1e-12) << i;
    ++checked;
  }
  EXPECT_LE(worst_error, 1e-9);
  EXPECT_EQ(checked, g.poses - 2);
  EXPECT_GT(smoother.stats().correction_steps, 0);
  EXPECT_EQ(smoother.stats().partial_relinearizations, 0);
  EXPECT_EQ(smoother.stats().batch_steps, 0);
}

TEST(SmootherTest, SkipFactorLeavesMoreUpdatesUncorrectedAndEachWithinItsBudget) {
  // correction_skip_factor: an update stays uncorrected while the decrease a correction
  // would bring is predicted below factor x tolerance x chi2. A loose tolerance (1e-2) makes
  // this small graph's new factors small against it, as a large map's are against 1e-4.
  // Against factor 1, more updates are skipped, and every update's estimate stays within
  // its budget of the dense optimum of its factors (measured worst 7.7e-3 and 2.5e-2).
  auto run = [](double factor, double* worst_excess) {
    SmootherOptions options = ServerModeWithCorrectionOptions();
    options.correction_local_hops = 0;  // the whole map's correction only
    options.correction_tolerance = 1e-2;
    options.correction_skip_factor = factor;
    Smoother smoother(options);
    testing::RandomGraphOptions g;
    g.poses = 40;
    g.loop_closures = 20;
    g.seed = 11;
    *worst_excess = WorstExcessOverTheOptimum(&smoother, g);
    std::printf("skip factor %g: %lld skipped, %lld CG steps, worst excess %.3g\n", factor,
                static_cast<long long>(smoother.stats().correction_skips),
                static_cast<long long>(smoother.stats().correction_steps), *worst_excess);
    return smoother.stats().correction_skips;
  };
  double worst_1 = 0.0, worst_3 = 0.0;
  const int64_t skipped_1 = run(1.0, &worst_1);
  const int64_t skipped_3 = run(3.0, &worst_3);
  EXPECT_GT(skipped_3, skipped_1);
  EXPECT_LE(worst_1, 1e-2);
  EXPECT_LE(worst_3, 3e-2);
}

TEST(SmootherTest, CorrectionOutOfStepsWithinTheSkipBudgetIsNoStall) {
  // A correction that runs out of outer steps with a decrease still predicted above the
  // tolerance but within the skip budget (factor x tolerance x chi2) has converged: no
  // stall, so no partial step on it, and the estimate stays within that budget of the
  // dense optimum, as an update left uncorrected does. One outer step per update and a
  // loose tolerance make such endings common on a small graph with heading noise: at
  // factor 3, five corrections end so (counted in a temporary build) and the stalls are 4
  // against 8 at factor 1, whose budget is the tolerance itself (every correction left
  // above it by its one step stalls, the old rule); 37 against 38 updates skipped, so the
  // skip budget's other use does not make the difference. Measured worst excess over the
  // optimum 1.1e-3 (factor 1) and 2.1e-3 (factor 3).
  auto run = [](double factor, double* worst_excess) {
    SmootherOptions options = ServerModeWithCorrectionOptions();
    options.correction_local_hops = 0;  // the whole map's correction only
    options.correction_tolerance = 1e-3;
    options.correction_iterations = 1;
    options.correction_skip_factor = factor;
    Smoother smoother(options);
    testing::RandomGraphOptions g;
    g.poses = 60;
    g.loop_closures = 30;
    g.seed = 5;
    g.sigma_theta_rad = 0.1;
    *worst_excess = WorstExcessOverTheOptimum(&smoother, g);
    std::printf(
        "skip factor %g: %lld stalls, %lld partial steps, %lld skipped, worst excess %.3g\n",
        factor, static_cast<long long>(smoother.stats().correction_stalls),
        static_cast<long long>(smoother.stats().partial_relinearizations),
        static_cast<long long>(smoother.stats().correction_skips), *worst_excess);
    return smoother.stats();
  };
  double worst_1 = 0.0, worst_3 = 0.0;
  const SmootherStats tight = run(1.0, &worst_1);
  const SmootherStats budget = run(3.0, &worst_3);
  EXPECT_GT(tight.correction_stalls, 0);
  EXPECT_LT(budget.correction_stalls, tight.correction_stalls);
  EXPECT_LE(budget.partial_relinearizations, tight.partial_relinearizations);
  EXPECT_LE(worst_1, 2e-3);
  EXPECT_LE(worst_3, 3e-3);
}

TEST(SmootherTest, NewPosesOfOneUpdateArePlacedTheSameWhateverOrderTheyWereAddedIn) {
  // The conjugate-gradient correction's mode places each new variable by the factor that
  // determines it, relative to its neighbours' estimates: a pose added before its
  // predecessor (so ordered before it in R) must still see the predecessor placed first.
  SmootherOptions options = ServerModeWithCorrectionOptions();
  options.correction_local_hops = 0;  // the whole map's correction only
  Smoother ascending(options), descending(options);
  const TrajectoryId t(0);
  AddRandomTrajectory(&ascending, t, 30, 5, true);
  AddRandomTrajectory(&descending, t, 30, 5, true);
  const Pose2 step(0.5, 0.1, 0.05);
  for (Smoother* smoother : {&ascending, &descending}) {
    const Pose2 last = smoother->FramePose({t, 29});
    for (int k = 0; k < 3; ++k) {
      const int i = smoother == &ascending ? 30 + k : 32 - k;
      // Initial values that the odometry does not agree with: the placement decides.
      ASSERT_TRUE(smoother->AddPose({t, i}, last).ok());
    }
    for (int i = 30; i < 33; ++i)
      ASSERT_TRUE(smoother->AddBetween({t, i - 1}, {t, i}, step, kCovariance).ok());
    ASSERT_TRUE(smoother->Update().status.ok());
  }
  EXPECT_GT(ascending.stats().correction_steps, 0);
  // The two R differ in their order, and the correction is preconditioned by R's blocks
  // rounded to float (FlatR): steps stopped at the tolerance differ by ~1e-9; a pose
  // placed from an unplaced predecessor would be off by the odometry's 0.5 m.
  for (int i = 0; i < 33; ++i) {
    EXPECT_LE(PoseError(ascending.Value(PoseKey{t, i}), descending.Value(PoseKey{t, i}))
                  .cwiseAbs()
                  .maxCoeff(),
              1e-7)
        << i;
  }
}

// A chain of 120 poses (seed 3, no loop closures) in trajectory 0, updated pose by pose.
void AddUpdatedChain(Smoother* smoother, PoseGraph* chain) {
  testing::RandomGraphOptions g;
  g.poses = 120;
  g.loop_closures = 0;
  g.seed = 3;
  *chain = testing::RandomGraph(g);
  for (int i = 0; i < g.poses; ++i) {
    ASSERT_TRUE(AddPoseAndItsEdges(smoother, *chain, TrajectoryId(0), i));
    ASSERT_TRUE(smoother->Update().status.ok());
  }
}

// A loop closure from pose i to pose j of `chain` (trajectory 0), measured exactly.
void AddTrueClosure(Smoother* smoother, const PoseGraph& chain, int i, int j) {
  const TrajectoryId t(0);
  ASSERT_TRUE(smoother
                  ->AddBetween({t, i}, {t, j},
                               Between(chain.vertices[i].pose, chain.vertices[j].pose), kCovariance)
                  .ok());
}

// 16 loop closures between the start and the end of `chain`, on different poses, not yet
// updated: eliminated through the chain's ordering, each row between them would take every
// later closure's column.
void AddClosuresAcrossTheChain(Smoother* smoother, const PoseGraph& chain) {
  const int poses = static_cast<int>(chain.vertices.size());
  for (int i = 0; i < 16; ++i) AddTrueClosure(smoother, chain, i, poses - 1 - 2 * i);
}

TEST(SmootherTest, UpdateThatWouldFillRPastTheFillTriggerIsABatchStepInstead) {
  // The server's configuration (the CG correction, reordering at 1.5x fill). A chain of
  // poses, then one update closing 16 loops between the start and the end of the chain
  // on different poses: eliminated through the chain's ordering, each row between them
  // would take every later closure's column (R several times its size); the update is a
  // batch step (a fresh ordering) instead, and the estimate is the optimum all the same.
  Smoother smoother(ServerModeWithCorrectionOptions());
  PoseGraph chain;
  ASSERT_NO_FATAL_FAILURE(AddUpdatedChain(&smoother, &chain));
  const int64_t batch_steps = smoother.stats().batch_steps_on_fill;
  const int64_t nonzeros = smoother.stats().nnz_r;
  ASSERT_NO_FATAL_FAILURE(AddClosuresAcrossTheChain(&smoother, chain));
  const UpdateResult result = smoother.Update();
  ASSERT_TRUE(result.status.ok());
  EXPECT_TRUE(result.batch_step);
  EXPECT_EQ(smoother.stats().batch_steps_on_fill, batch_steps + 1);
  // A fresh ordering of the chain with its 16 closures, not the rows between them filled.
  EXPECT_LT(smoother.stats().nnz_r, 2 * nonzeros);

  const DenseOracle oracle(smoother.ActiveFactors());
  const Values optimum = oracle.Solve(CurrentValues(smoother), 1e-14, 50);
  EXPECT_NEAR(smoother.Chi2(), oracle.Chi2(optimum), 1e-3 * oracle.Chi2(optimum));
}

// The pending update of `smoother` (over `chain`) past a Givens budget, with the batch step
// that replaces it failing (its ordering): the Givens updates stopped at the budget and
// were taken back, so the smoother is exactly as before the update (estimates, chi2, R's
// size), and the next update makes the batch step and ends at the optimum.
void ExpectAFailedBatchStepLeavesTheStateAsItWas(Smoother* smoother, const PoseGraph& chain) {
  const TrajectoryId t(0);
  const int poses = static_cast<int>(chain.vertices.size());
  std::vector<Pose2> before;
  for (int i = 0; i < poses; ++i) before.push_back(smoother->Value(PoseKey{t, i}));
  const double chi2_before = smoother->Chi2();
  const SmootherStats stats_before = smoother->stats();
  FailNextOrderingsForTesting(1);
  const UpdateResult failed = smoother->Update();
  FailNextOrderingsForTesting(0);
  ASSERT_FALSE(failed.status.ok());
  EXPECT_EQ(smoother->stats().failed_batch_steps, stats_before.failed_batch_steps + 1);
  EXPECT_EQ(smoother->stats().nnz_r, stats_before.nnz_r);
  EXPECT_EQ(smoother->stats().givens_block_rows, stats_before.givens_block_rows);
  EXPECT_EQ(smoother->Chi2(), chi2_before);
  for (int i = 0; i < poses; ++i) {
    const Pose2 value = smoother->Value(PoseKey{t, i});
    EXPECT_EQ(value.x(), before[i].x()) << i;
    EXPECT_EQ(value.y(), before[i].y()) << i;
    EXPECT_EQ(value.theta(), before[i].theta()) << i;
  }

  const UpdateResult result = smoother->Update();
  ASSERT_TRUE(result.status.ok());
  EXPECT_TRUE(result.batch_step);
  // The failed batch step is counted as tried, as every batch step is.
  EXPECT_EQ(smoother->stats().batch_steps_on_fill, stats_before.batch_steps_on_fill + 2);
  const DenseOracle oracle(smoother->ActiveFactors());
  const Values optimum = oracle.Solve(CurrentValues(*smoother), 1e-14, 50);
  EXPECT_NEAR(smoother->Chi2(), oracle.Chi2(optimum), 1e-3 * oracle.Chi2(optimum));
}

TEST(SmootherTest, GivensUpdatePastItsFillBudgetWhoseBatchStepFailsLeavesTheStateAsItWas) {
  Smoother smoother(ServerModeWithCorrectionOptions());
  PoseGraph chain;
  ASSERT_NO_FATAL_FAILURE(AddUpdatedChain(&smoother, &chain));
  ASSERT_NO_FATAL_FAILURE(AddClosuresAcrossTheChain(&smoother, chain));
  ExpectAFailedBatchStepLeavesTheStateAsItWas(&smoother, chain);
}

// 200 loop closures from one pose near the start of `chain` to its last pose, not yet
// updated: their rows ride together through every row of the chain between them (200
// triples carried through ~110 block rows), while each of those rows gains one block
// only (the last pose's column).
void AddManyClosuresToTheLastPose(Smoother* smoother, const PoseGraph& chain) {
  const int last = static_cast<int>(chain.vertices.size()) - 1;
  for (int k = 0; k < 200; ++k) AddTrueClosure(smoother, chain, 5, last);
}

TEST(SmootherTest, UpdatePastItsGivensWorkBudgetIsABatchStepInstead) {
  // The server's configuration. The update above adds little fill (the fill budget lets it
  // through: without the work budget it is a Givens update) but carries many rows through
  // R; with the work budget it is a batch step. Both end at the optimum.
  SmootherOptions without_budget = ServerModeWithCorrectionOptions();
  without_budget.givens_work_budget = 0.0;
  for (const SmootherOptions& options : {ServerModeWithCorrectionOptions(), without_budget}) {
    const bool budgeted = options.givens_work_budget > 0;
    Smoother smoother(options);
    PoseGraph chain;
    ASSERT_NO_FATAL_FAILURE(AddUpdatedChain(&smoother, &chain));
    const int64_t batch_steps = smoother.stats().batch_steps_on_fill;
    ASSERT_NO_FATAL_FAILURE(AddManyClosuresToTheLastPose(&smoother, chain));
    const UpdateResult result = smoother.Update();
    ASSERT_TRUE(result.status.ok());
    EXPECT_EQ(result.batch_step, budgeted) << budgeted;
    EXPECT_EQ(smoother.stats().batch_steps_on_fill, batch_steps + (budgeted ? 1 : 0));
    const DenseOracle oracle(smoother.ActiveFactors());
    const Values optimum = oracle.Solve(CurrentValues(smoother), 1e-14, 50);
    EXPECT_NEAR(smoother.Chi2(), oracle.Chi2(optimum), 1e-3 * oracle.Chi2(optimum)) << budgeted;
  }
}

TEST(SmootherTest, GivensUpdatePastItsWorkBudgetWhoseBatchStepFailsLeavesTheStateAsItWas) {
  // The work budget stops the Givens update before it writes R, as the fill budget does.
  Smoother smoother(ServerModeWithCorrectionOptions());
  PoseGraph chain;
  ASSERT_NO_FATAL_FAILURE(AddUpdatedChain(&smoother, &chain));
  ASSERT_NO_FATAL_FAILURE(AddManyClosuresToTheLastPose(&smoother, chain));
  ExpectAFailedBatchStepLeavesTheStateAsItWas(&smoother, chain);
}

TEST(SmootherTest, CovariancesEqualDenseInverseAtConvergence) {
  SmootherOptions options;
  options.convergence_step = 1e-13;  // R linearised at the estimate itself
  Smoother smoother(options);
  AddRandomTrajectory(&smoother, TrajectoryId(0), 30, 8, false);
  AddRandomTrajectory(&smoother, TrajectoryId(1), 25, 9, false);
  ASSERT_TRUE(smoother
                  .AddEncounter({TrajectoryId(0), 10}, {TrajectoryId(1), 3}, Pose2(0.5, 0.2, 0.1),
                                kCovariance)
                  .ok());
  ASSERT_TRUE(smoother
                  .AddEncounter({TrajectoryId(1), 20}, {TrajectoryId(0), 25}, Pose2(-0.5, 0.2, 3.0),
                                kCovariance)
                  .ok());
  ASSERT_TRUE(smoother.BatchOptimize().status.ok());
  const DenseOracle oracle(smoother.ActiveFactors());
  const Values values = CurrentValues(smoother);
  const std::vector<Key> keys = {AnchorKey{TrajectoryId(0)}, AnchorKey{TrajectoryId(1)},
                                 PoseKey{TrajectoryId(0), 10}, PoseKey{TrajectoryId(1), 3},
                                 PoseKey{TrajectoryId(0), 0}};
  const Eigen::MatrixXd expected = oracle.Covariance(values, keys);
  const Eigen::MatrixXd joint = smoother.JointCovariance(keys);
  EXPECT_LT((joint - expected).cwiseAbs().maxCoeff(), 1e-9 * expected.cwiseAbs().maxCoeff());
  for (size_t k = 0; k < keys.size(); ++k) {
    EXPECT_LT((smoother.MarginalCovariance(keys[k]) - expected.block<3, 3>(3 * k, 3 * k))
                  .cwiseAbs()
                  .maxCoeff(),
              1e-9 * expected.cwiseAbs().maxCoeff());
  }
  EXPECT_THROW(smoother.MarginalCovariance(PoseKey{TrajectoryId(7), 0}), std::invalid_argument);
}

TEST(SmootherTest, CovarianceOfIncrementalStateEqualsDenseInverseOfItsSystem) {
  // Between batch steps R mixes linearisation points; its covariance is still exactly
  // (R^T R)^-1, which the oracle rebuilds from the factors only at convergence. Here:
  // no batch step at all and linear-enough measurements, so both agree closely.
  SmootherOptions options;
  options.batch_every_updates = 0;
  options.batch_when_fill_grows = 0;
  Smoother smoother(options);
  for (int i = 0; i < 20; ++i) {
    ASSERT_TRUE(smoother.AddPose({TrajectoryId(0), i}, Pose2(i, 0, 0)).ok());
    if (i > 0) {
      ASSERT_TRUE(smoother
                      .AddBetween({TrajectoryId(0), i - 1}, {TrajectoryId(0), i}, Pose2(1, 0, 0),
                                  kCovariance)
                      .ok());
    }
    ASSERT_TRUE(smoother.Update().status.ok());
  }
  ASSERT_TRUE(
      smoother.AddBetween({TrajectoryId(0), 3}, {TrajectoryId(0), 17}, Pose2(14, 0, 0), kCovariance)
          .ok());
  ASSERT_TRUE(smoother.Update().status.ok());
  const DenseOracle oracle(smoother.ActiveFactors());
  const std::vector<Key> keys = {PoseKey{TrajectoryId(0), 19}, PoseKey{TrajectoryId(0), 5}};
  const Eigen::MatrixXd expected = oracle.Covariance(CurrentValues(smoother), keys);
  EXPECT_LT((smoother.JointCovariance(keys) - expected).cwiseAbs().maxCoeff(), 1e-9);
}

// Three robots with drifting odometry (no loop closures) meet now and then, so each
// encounter turns an anchor by degrees. Without relinearisation, Givens updates keep
// encounters linearised at old anchor headings (metres apart at the far end of a
// trajectory) and the estimate wanders off the optimum between batch steps; with
// relinearize_threshold the estimate after every update is the optimum of the factors
// so far (to the threshold's order) and the anchor covariances are the dense inverse's.
TEST(SmootherTest, RelinearizeThresholdKeepsEveryUpdateAtTheOptimum) {
  constexpr int kRobots = 3, kPoses = 45;
  std::vector<PoseGraph> graphs;
  std::vector<Pose2> offsets = {Pose2(0, 0, 0), Pose2(4, -3, 1.2), Pose2(-5, 2, -2.0)};
  for (int r = 0; r < kRobots; ++r) {
    testing::RandomGraphOptions g;
    g.poses = kPoses;
    g.loop_closures = 0;
    g.sigma_theta_rad = 0.04;
    g.arena_radius_m = 6.0;
    g.seed = 40 + r;
    graphs.push_back(testing::RandomGraph(g));
  }
  auto truth = [&](int r, int i) { return Compose(offsets[r], graphs[r].vertices[i].pose); };

  double worst_error[2] = {0, 0}, worst_covariance[2] = {0, 0};
  for (int mode = 0; mode < 2; ++mode) {
    SmootherOptions options;
    options.batch_every_updates = 10;
    options.relinearize_threshold = mode == 0 ? 0.0 : 0.01;
    Smoother smoother(options);
    int encounters = 0;
    for (int i = 0; i < kPoses; ++i) {
      for (int r = 0; r < kRobots; ++r) {
        const Pose2 initial = i == 0 ? Pose2()
                                     : Compose(smoother.FramePose({TrajectoryId(r), i - 1}),
                                               graphs[r].edges[i - 1].measured_T_from_to);
        ASSERT_TRUE(smoother.AddPose({TrajectoryId(r), i}, initial).ok());
        if (i > 0) {
          ASSERT_TRUE(smoother
                          .AddBetween({TrajectoryId(r), i - 1}, {TrajectoryId(r), i},
                                      graphs[r].edges[i - 1].measured_T_from_to,
                                      graphs[r].edges[i - 1].information.inverse())
                          .ok());
        }
      }
      if (i >= 6 && i % 4 == 2) {  // robots (a, a+1) meet; indices lag a little
        const int a = (i / 4) % kRobots, b = (a + 1) % kRobots, j = i - (i / 4) % 3;
        const Pose2 z = Between(truth(a, i), truth(b, j));
        ASSERT_TRUE(
            smoother.AddEncounter({TrajectoryId(a), i}, {TrajectoryId(b), j}, z, kCovariance).ok());
        ++encounters;
      }
      ASSERT_TRUE(smoother.Update().status.ok());
      if (i < 10 || i % 6 != 0) continue;
      // The optimum of the factors so far, and its covariance, from the dense oracle.
      const DenseOracle oracle(smoother.ActiveFactors());
      const Values optimum = oracle.Solve(CurrentValues(smoother));
      std::vector<Key> anchors;
      for (int r = 0; r < kRobots; ++r) {
        if (smoother.IsAnchored(TrajectoryId(r))) anchors.push_back(AnchorKey{TrajectoryId(r)});
      }
      for (const auto& [key, value] : optimum) {
        worst_error[mode] = std::max(worst_error[mode],
                                     PoseError(smoother.Value(key), value).cwiseAbs().maxCoeff());
      }
      if (anchors.empty()) continue;
      const Eigen::MatrixXd expected = oracle.Covariance(optimum, anchors);
      const Eigen::MatrixXd actual = smoother.JointCovariance(anchors);
      worst_covariance[mode] =
          std::max(worst_covariance[mode],
                   ((actual - expected).cwiseAbs().maxCoeff()) / expected.cwiseAbs().maxCoeff());
    }
    EXPECT_GE(encounters, 8);
  }
  std::printf("largest distance to the optimum after an update: %.4f (iSAM), %.4f (threshold)\n",
              worst_error[0], worst_error[1]);
  std::printf("largest relative anchor covariance error: %.4f (iSAM), %.4f (threshold)\n",
              worst_covariance[0], worst_covariance[1]);
  EXPECT_LT(worst_error[1], 0.02);
  EXPECT_LT(worst_covariance[1], 0.02);
  EXPECT_GT(worst_error[0], worst_error[1]);
}

// Many trajectories that meet, replayed update by update in the server's configuration,
// with and without each trajectory's newest pose kept last in the orderings. Kept last,
// the newest poses and the anchors form a dense clique at R's root in every ordering;
// without it R after a fresh ordering is smaller. Both are the same least-squares problem:
// every update ends within the server's tolerance of the dense optimum, and a final batch
// step reaches the same optimum.
TEST(SmootherTest, LatestPosesNotKeptLastShrinkRAndReachTheSameOptimum) {
  testing::RandomGraphOptions g;
  g.poses = 240;
  g.loop_closures = 120;
  g.seed = 21;
  const PoseGraph graph = testing::RandomGraph(g);
  const GraphReplay replay(graph, 12);
  ASSERT_TRUE(replay.status().ok());
  ASSERT_GT(replay.num_encounters(), 0);
  int64_t nonzeros[2] = {0, 0};
  double chi2[2] = {0, 0};
  for (int last = 0; last < 2; ++last) {
    SmootherOptions options = ServerModeWithCorrectionOptions();
    options.latest_poses_last = last == 1;
    Smoother smoother(options);
    double worst = 0.0;
    for (int k = 0; k < replay.num_steps(); ++k) {
      ASSERT_TRUE(replay.AddStep(k, &smoother).ok());
      ASSERT_TRUE(smoother.Update().status.ok()) << k;
      if (k % 10 != 9) continue;
      const DenseOracle oracle(smoother.ActiveFactors());
      const double optimum = oracle.Chi2(oracle.Solve(CurrentValues(smoother), 1e-10, 50));
      worst = std::max(worst, (smoother.Chi2() - optimum) / optimum);
    }
    EXPECT_LE(worst, 1e-3) << last;
    ASSERT_TRUE(smoother.BatchOptimize(1e-9).status.ok());
    nonzeros[last] = smoother.stats().nnz_r;
    chi2[last] = smoother.Chi2();
    const DenseOracle oracle(smoother.ActiveFactors());
    const double optimum = oracle.Chi2(oracle.Solve(CurrentValues(smoother), 1e-12, 50));
    EXPECT_NEAR(chi2[last], optimum, 1e-9 * optimum) << last;
  }
  std::printf("nnz(R) after the final batch step: %lld newest poses free, %lld kept last\n",
              static_cast<long long>(nonzeros[0]), static_cast<long long>(nonzeros[1]));
  EXPECT_LT(nonzeros[0], nonzeros[1]);
  EXPECT_NEAR(chi2[0], chi2[1], 1e-9 * chi2[1]);
}

// A stalled correction whose drift covers most of the map (a long chain's loop closure
// after heading drift): the partial step would re-eliminate more than half of R, so the
// update takes a batch step instead, and relinearises nothing more after it (every row is
// then at one point; a correction that still stalls stalls on the nonlinearity). One outer
// step per correction makes the closure's correction stall.
TEST(SmootherTest, StallWhoseDriftCoversMostOfRIsOneBatchStepInsteadOfPartialSteps) {
  SmootherOptions options = ServerModeWithCorrectionOptions();
  options.correction_iterations = 1;
  Smoother smoother(options);
  testing::RandomGraphOptions g;
  g.poses = 120;
  g.loop_closures = 0;
  g.sigma_theta_rad = 0.05;
  g.seed = 7;
  const PoseGraph graph = testing::RandomGraph(g);
  const TrajectoryId t(0);
  for (int i = 0; i < g.poses; ++i) {
    ASSERT_TRUE(AddPoseAndItsEdges(&smoother, graph, t, i));
    ASSERT_TRUE(smoother.Update().status.ok());
  }
  const SmootherStats before = smoother.stats();
  const int last = g.poses - 1;
  ASSERT_TRUE(smoother
                  .AddBetween({t, 0}, {t, last},
                              Between(graph.vertices[0].pose, graph.vertices[last].pose),
                              kCovariance)
                  .ok());
  const UpdateResult closure = smoother.Update();
  ASSERT_TRUE(closure.status.ok());
  const SmootherStats after = smoother.stats();
  std::printf(
      "closure: %lld stalls, %lld batch steps on drift, %lld partial steps\n",
      static_cast<long long>(after.correction_stalls - before.correction_stalls),
      static_cast<long long>(after.batch_steps_on_drift - before.batch_steps_on_drift),
      static_cast<long long>(after.partial_relinearizations - before.partial_relinearizations));
  EXPECT_GT(after.correction_stalls, before.correction_stalls);
  EXPECT_TRUE(closure.batch_step);
  EXPECT_EQ(after.batch_steps_on_drift - before.batch_steps_on_drift, 1);
  EXPECT_EQ(after.partial_relinearizations, before.partial_relinearizations);
  // The next updates (no new factors) converge to the dense optimum.
  for (int k = 0; k < 20; ++k) ASSERT_TRUE(smoother.Update().status.ok());
  const DenseOracle oracle(smoother.ActiveFactors());
  const double optimum = oracle.Chi2(oracle.Solve(CurrentValues(smoother), 1e-10, 20));
  std::printf("chi2 %.6f, optimum %.6f\n", smoother.Chi2(), optimum);
  EXPECT_LE(smoother.Chi2(), optimum * (1 + 1e-3));
}

// Two trajectories (one encounter joins them) with relinearisation at 0.01: partial steps
// run, a forced ordering failure in the middle changes nothing, and the end is the dense
// optimum. (The per-update checks of R are tests/per_update_oracle_test.cc; this one is
// here so that the sanitizer build of the solver's own tests runs the partial steps.)
TEST(SmootherTest, PartialRelinearisationAndAFailedBatchStepEndAtTheOptimum) {
  SmootherOptions options;
  options.relinearize_threshold = 0.01;
  options.batch_every_updates = 10;
  Smoother smoother(options);
  AddRandomTrajectory(&smoother, TrajectoryId(0), 60, 41, true);
  AddRandomTrajectory(&smoother, TrajectoryId(1), 60, 42, true);
  ASSERT_TRUE(smoother
                  .AddEncounter({TrajectoryId(0), 59}, {TrajectoryId(1), 59}, Pose2(0.5, 0.0, 0.1),
                                kCovariance)
                  .ok());
  ASSERT_TRUE(smoother
                  .AddEncounter({TrajectoryId(0), 30}, {TrajectoryId(1), 20}, Pose2(0.2, 0.1, 0.0),
                                kCovariance)
                  .ok());
  const Values before = CurrentValues(smoother);
  FailNextOrderingsForTesting(1);
  const UpdateResult failed = smoother.BatchOptimize();
  EXPECT_EQ(failed.status.code(), ErrorCode::kNumericalFailure);
  const Values after = CurrentValues(smoother);
  for (const auto& [key, value] : before) {
    EXPECT_EQ(value.x(), after.at(key).x());
    EXPECT_EQ(value.theta(), after.at(key).theta());
  }
  ASSERT_TRUE(smoother.Update().status.ok());
  EXPECT_GT(smoother.stats().partial_relinearizations, 0);
  EXPECT_EQ(smoother.stats().failed_batch_steps, 1);
  ASSERT_TRUE(smoother.BatchOptimize(1e-10).status.ok());
  const testing::DenseOracle oracle(smoother.ActiveFactors());
  const Values optimum = oracle.Solve(CurrentValues(smoother), 1e-12);
  EXPECT_NEAR(smoother.Chi2(), oracle.Chi2(optimum), 1e-9 * oracle.Chi2(optimum));
}

}  // namespace
}  // namespace anchormap
