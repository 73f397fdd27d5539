// The relative formulation (anchors) against the global baseline: the same merged map;
// anchors created exactly at first encounters; only anchors move at a first encounter;
// one gauge per group of trajectories, including groups that form apart and join later.

#include <gtest/gtest.h>

#include "common/io/graph_file.h"
#include "tests/testing/data_path.h"
#include "tests/testing/dense_oracle.h"
#include "tests/testing/graph_replay.h"
#include "tests/testing/random_graph.h"

namespace anchormap {
namespace {

const Eigen::Matrix3d kCovariance = Eigen::Vector3d(0.01, 0.01, 0.001).asDiagonal();

// Every pose in the frame of the first robot's first pose.
std::vector<Pose2> MergedInFirstFrame(const Smoother& smoother, const GraphReplay& replay) {
  const Pose2 origin = smoother.GlobalPose(replay.KeyOf(0));
  std::vector<Pose2> poses;
  for (int64_t id = 0; id < replay.num_poses(); ++id) {
    poses.push_back(Between(origin, smoother.GlobalPose(replay.KeyOf(id))));
  }
  return poses;
}

struct Run {
  std::vector<Pose2> merged;
  double chi2;
  int64_t iterations;
};

Run Replay(const PoseGraph& graph, int robots, Formulation formulation) {
  SmootherOptions options;
  options.formulation = formulation;
  const GraphReplay replay(graph, robots);
  Smoother smoother(options);
  for (int k = 0; k < replay.num_steps(); ++k) {
    EXPECT_TRUE(replay.AddStep(k, &smoother).ok());
    EXPECT_TRUE(smoother.Update().status.ok());
  }
  EXPECT_TRUE(smoother.BatchOptimize(1e-9).status.ok());
  for (TrajectoryId t : smoother.Trajectories()) {
    EXPECT_EQ(smoother.GroupRoot(t), smoother.GroupRoot(TrajectoryId(0)))
        << "trajectory " << t << " not merged";
  }
  return {MergedInFirstFrame(smoother, replay), smoother.Chi2(),
          smoother.stats().iterations_to_convergence};
}

void ExpectSameMergedMap(const PoseGraph& graph, int robots, double single_robot_chi2) {
  const Run relative = Replay(graph, robots, Formulation::kRelative);
  for (Formulation f : {Formulation::kGlobal, Formulation::kGlobalMoved}) {
    SCOPED_TRACE(std::string(ToString(f)) + ", robots " + std::to_string(robots));
    const Run global = Replay(graph, robots, f);
    double worst = 0.0;
    for (size_t i = 0; i < relative.merged.size(); ++i) {
      worst =
          std::max(worst, PoseError(relative.merged[i], global.merged[i]).cwiseAbs().maxCoeff());
    }
    EXPECT_LE(worst, 1e-6);
    EXPECT_NEAR(relative.chi2, global.chi2, 1e-6 * global.chi2);
  }
  // A split only drops edges: its optimum cannot be above the single-robot one.
  EXPECT_LE(relative.chi2, single_robot_chi2 * (1 + 1e-9));
}

double SingleRobotChi2(const PoseGraph& graph) {
  return Replay(graph, 1, Formulation::kRelative).chi2;
}

TEST(FormulationsTest, RelativeAndGlobalGiveTheSameMergedMapOnRandomSplits) {
  testing::RandomGraphOptions options;
  options.poses = 240;
  options.loop_closures = 60;
  options.max_loop_distance_m = 5.0;
  const PoseGraph graph = testing::RandomGraph(options);
  const double single = SingleRobotChi2(graph);
  ExpectSameMergedMap(graph, 2, single);
  ExpectSameMergedMap(graph, 3, single);
}

TEST(FormulationsTest, RelativeAndGlobalGiveTheSameMergedMapOnIntel) {
  ANCHORMAP_REQUIRE_DATA(path, "posegraph/intel.g2o");
  PoseGraph graph;
  ASSERT_TRUE(ReadPoseGraph(path, &graph).ok());
  const double single = SingleRobotChi2(graph);
  ExpectSameMergedMap(graph, 2, single);
  ExpectSameMergedMap(graph, 3, single);
}

// Two trajectories solved on their own; returns their local poses.
std::vector<Pose2> BuildTwoTrajectories(Smoother* smoother, int poses) {
  std::vector<Pose2> locals;
  for (int64_t number : {0, 1}) {
    const TrajectoryId t(number);
    testing::RandomGraphOptions options;
    options.poses = poses;
    options.loop_closures = poses / 4;
    options.seed = 20 + static_cast<uint32_t>(number);
    const PoseGraph graph = testing::RandomGraph(options);
    const GraphReplay replay(graph, 1);
    for (int k = 0; k < replay.num_steps(); ++k) {
      // GraphReplay writes trajectory 0; re-key by hand for trajectory t.
      const int32_t i = k;
      Pose2 initial;
      if (i > 0) {
        initial = Compose(smoother->FramePose({t, i - 1}), graph.edges[i - 1].measured_T_from_to);
      }
      EXPECT_TRUE(smoother->AddPose({t, i}, initial).ok());
      for (const GraphEdge& e : graph.edges) {
        if (e.to == i || (e.from == i && e.to < i)) {
          EXPECT_TRUE(smoother
                          ->AddBetween({t, static_cast<int32_t>(e.from)},
                                       {t, static_cast<int32_t>(e.to)}, e.measured_T_from_to,
                                       e.information.inverse())
                          .ok());
        }
      }
      EXPECT_TRUE(smoother->Update().status.ok());
    }
  }
  EXPECT_TRUE(smoother->BatchOptimize().status.ok());
  for (int64_t t : {0, 1}) {
    for (int i = 0; i < poses; ++i) locals.push_back(smoother->FramePose({TrajectoryId(t), i}));
  }
  return locals;
}

TEST(FormulationsTest, AtAFirstEncounterOnlyTheAnchorsMove) {
  SmootherOptions options;
  options.batch_every_updates = 0;
  options.batch_when_fill_grows = 0;
  Smoother smoother(options);
  const int poses = 50;
  const std::vector<Pose2> before = BuildTwoTrajectories(&smoother, poses);
  EXPECT_FALSE(smoother.IsAnchored(TrajectoryId(0)));
  EXPECT_FALSE(smoother.IsAnchored(TrajectoryId(1)));

  ASSERT_TRUE(smoother
                  .AddEncounter({TrajectoryId(0), 30}, {TrajectoryId(1), 12}, Pose2(1.0, -0.5, 0.7),
                                kCovariance)
                  .ok());
  const UpdateResult result = smoother.Update();
  ASSERT_TRUE(result.status.ok());
  EXPECT_FALSE(result.batch_step);
  EXPECT_EQ(result.anchors_created, 2);
  EXPECT_TRUE(smoother.IsAnchored(TrajectoryId(0)));
  EXPECT_TRUE(smoother.IsAnchored(TrajectoryId(1)));

  double worst = 0.0;
  for (int64_t t : {0, 1}) {
    for (int i = 0; i < poses; ++i) {
      worst =
          std::max(worst, PoseError(smoother.FramePose({TrajectoryId(t), i}), before[t * poses + i])
                              .cwiseAbs()
                              .maxCoeff());
    }
  }
  EXPECT_LE(worst, 1e-9);
  // The first anchor defines the global frame; the second satisfies the encounter exactly.
  EXPECT_LE(PoseError(*smoother.Anchor(TrajectoryId(0)), Pose2()).norm(), 1e-9);
  const Pose2 predicted = Between(smoother.GlobalPose({TrajectoryId(0), 30}),
                                  smoother.GlobalPose({TrajectoryId(1), 12}));
  EXPECT_LE(PoseError(predicted, Pose2(1.0, -0.5, 0.7)).norm(), 1e-9);

  // A second encounter now propagates information into both graphs, like a loop closure.
  ASSERT_TRUE(smoother
                  .AddEncounter({TrajectoryId(0), 45}, {TrajectoryId(1), 40}, Pose2(0.3, 0.1, -0.2),
                                kCovariance)
                  .ok());
  ASSERT_TRUE(smoother.Update().status.ok());
  EXPECT_GT(PoseError(smoother.FramePose({TrajectoryId(1), 40}), before[poses + 40])
                .cwiseAbs()
                .maxCoeff(),
            1e-6);
}

// Five robots A..E (0..4), each a short straight line.
void AddLine(Smoother* smoother, TrajectoryId t, int poses) {
  for (int i = 0; i < poses; ++i) {
    ASSERT_TRUE(smoother->AddPose({t, i}, Pose2(i, 0, 0)).ok());
    if (i > 0) {
      ASSERT_TRUE(
          smoother->AddBetween({t, i - 1}, {t, i}, Pose2(1, 0, 0.02 * t.value()), kCovariance)
              .ok());
    }
  }
}

TEST(FormulationsTest, SeparateGroupsKeepTheirOwnGaugeUntilTheyJoin) {
  for (Formulation formulation :
       {Formulation::kRelative, Formulation::kGlobal, Formulation::kGlobalMoved}) {
    SCOPED_TRACE(ToString(formulation));
    SmootherOptions options;
    options.formulation = formulation;
    Smoother smoother(options);
    for (int64_t t = 0; t < 5; ++t) AddLine(&smoother, TrajectoryId(t), 10);
    ASSERT_TRUE(smoother.Update().status.ok());
    const bool relative = formulation == Formulation::kRelative;

    // B-C and D-E form two groups first.
    ASSERT_TRUE(
        smoother
            .AddEncounter({TrajectoryId(1), 5}, {TrajectoryId(2), 2}, Pose2(0, 2, 0.5), kCovariance)
            .ok());
    ASSERT_TRUE(smoother
                    .AddEncounter({TrajectoryId(3), 4}, {TrajectoryId(4), 8}, Pose2(1, -2, -0.5),
                                  kCovariance)
                    .ok());
    UpdateResult result = smoother.Update();
    ASSERT_TRUE(result.status.ok()) << result.status.message();
    EXPECT_EQ(smoother.IsAnchored(TrajectoryId(0)), false);
    EXPECT_EQ(smoother.IsAnchored(TrajectoryId(1)), relative);
    EXPECT_EQ(smoother.IsAnchored(TrajectoryId(3)), relative);
    EXPECT_EQ(smoother.GroupRoot(TrajectoryId(2)), TrajectoryId(1));
    EXPECT_EQ(smoother.GroupRoot(TrajectoryId(4)), TrajectoryId(3));
    EXPECT_NE(smoother.GroupRoot(TrajectoryId(1)), smoother.GroupRoot(TrajectoryId(3)));
    if (relative) {
      EXPECT_FALSE(result.batch_step);  // anchors need no batch step here
    }

    // A meets B: A joins B's group (relative) or B's group joins A's (global).
    ASSERT_TRUE(
        smoother
            .AddEncounter({TrajectoryId(0), 9}, {TrajectoryId(1), 0}, Pose2(3, 0, 0), kCovariance)
            .ok());
    ASSERT_TRUE(smoother.Update().status.ok());
    EXPECT_EQ(smoother.GroupRoot(TrajectoryId(0)), smoother.GroupRoot(TrajectoryId(2)));
    // Then A meets E: the two groups join and one gauge prior goes.
    ASSERT_TRUE(smoother
                    .AddEncounter({TrajectoryId(0), 3}, {TrajectoryId(4), 0}, Pose2(0, -3, 0.2),
                                  kCovariance)
                    .ok());
    result = smoother.Update();
    ASSERT_TRUE(result.status.ok()) << result.status.message();
    EXPECT_TRUE(result.batch_step);
    for (int64_t t = 0; t < 5; ++t) {
      EXPECT_EQ(smoother.GroupRoot(TrajectoryId(t)), smoother.GroupRoot(TrajectoryId(0)));
    }

    // One more cycle between the groups, then compare with a dense solve.
    ASSERT_TRUE(smoother
                    .AddEncounter({TrajectoryId(2), 9}, {TrajectoryId(3), 9}, Pose2(0.5, 0.5, 0.1),
                                  kCovariance)
                    .ok());
    ASSERT_TRUE(smoother.BatchOptimize().status.ok());
    int priors = 0;
    for (const Factor& f : smoother.ActiveFactors())
      priors += std::holds_alternative<PriorFactor>(f);
    EXPECT_EQ(priors, relative ? 5 + 1 : 1);  // origins + one anchor gauge; or one origin
    testing::Values values;
    for (const Factor& f : smoother.ActiveFactors()) {
      for (const Key& key : FactorKeys(f)) values[key] = smoother.Value(key);
    }
    const testing::DenseOracle oracle(smoother.ActiveFactors());
    EXPECT_NEAR(smoother.Chi2(), oracle.Chi2(oracle.Solve(values)), 1e-9 * smoother.Chi2());
  }
}

}  // namespace
}  // namespace anchormap
