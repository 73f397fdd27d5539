// After a final batch step, the incremental smoother (Givens updates, periodic batch
// steps, solution after every step) must reach the same solution as a pure batch solve
// of the same measurements: on seeded random graphs and on the real graphs of
// ../shared/data/posegraph (skipped with a message when absent).

#include <gtest/gtest.h>
#include <Eigen/Dense>

#include "common/io/graph_file.h"
#include "tests/testing/data_path.h"
#include "tests/testing/graph_replay.h"
#include "tests/testing/random_graph.h"

namespace anchormap {
namespace {

// Both final solves converge well below the 1e-6 the comparison asks for.
constexpr double kTightConvergence = 1e-9;

struct Comparison {
  double max_pose_difference = 0.0;
  double chi2_incremental = 0.0;
  double chi2_batch = 0.0;
};

// `batch_from_vertices`: start the batch solve from the file's own initial estimate;
// needed where composed odometry leads Gauss-Newton into a local minimum (MIT).
Comparison CompareIncrementalWithBatch(const PoseGraph& graph, int robots,
                                       const SmootherOptions& options,
                                       bool batch_from_vertices = false) {
  const GraphReplay replay(graph, robots);
  Smoother incremental(options);
  for (int k = 0; k < replay.num_steps(); ++k) {
    EXPECT_TRUE(replay.AddStep(k, &incremental).ok());
    const UpdateResult result = incremental.Update();
    EXPECT_TRUE(result.status.ok()) << "step " << k << ": " << result.status.message();
  }
  EXPECT_TRUE(incremental.BatchOptimize(kTightConvergence).status.ok());

  SmootherOptions batch_options = options;
  batch_options.batch_every_updates = 0;
  Smoother batch(batch_options);
  EXPECT_TRUE(replay.AddAll(&batch, batch_from_vertices).ok());
  EXPECT_TRUE(batch.BatchOptimize(kTightConvergence).status.ok());

  // Compared in the frame of pose 0, so that the two gauges need not coincide.
  Comparison c;
  const Pose2 origin_incremental = incremental.GlobalPose(replay.KeyOf(0));
  const Pose2 origin_batch = batch.GlobalPose(replay.KeyOf(0));
  for (int64_t id = 0; id < replay.num_poses(); ++id) {
    const PoseKey key = replay.KeyOf(id);
    const double d = PoseError(Between(origin_incremental, incremental.GlobalPose(key)),
                               Between(origin_batch, batch.GlobalPose(key)))
                         .cwiseAbs()
                         .maxCoeff();
    c.max_pose_difference = std::max(c.max_pose_difference, d);
  }
  c.chi2_incremental = incremental.Chi2();
  c.chi2_batch = batch.Chi2();
  return c;
}

void ExpectAgreement(const Comparison& c) {
  EXPECT_LE(c.max_pose_difference, 1e-6);
  EXPECT_LE(std::abs(c.chi2_incremental - c.chi2_batch), 1e-6 * c.chi2_batch);
}

TEST(IncrementalVsBatchTest, RandomGraphs) {
  for (uint32_t seed : {1u, 2u, 3u}) {
    testing::RandomGraphOptions graph_options;
    graph_options.poses = 300;
    graph_options.loop_closures = 80;
    graph_options.seed = seed;
    const PoseGraph graph = testing::RandomGraph(graph_options);
    for (double threshold : {0.0, 1e-3}) {
      SmootherOptions options;
      options.batch_every_updates = 25;
      options.backsubstitution_threshold = threshold;
      SCOPED_TRACE("seed " + std::to_string(seed) + ", threshold " + std::to_string(threshold));
      ExpectAgreement(CompareIncrementalWithBatch(graph, 1, options));
      ExpectAgreement(CompareIncrementalWithBatch(graph, 3, options));
    }
  }
}

void RealGraph(const char* file, bool batch_from_vertices = false) {
  ANCHORMAP_REQUIRE_DATA(path, file);
  PoseGraph graph;
  const Status status = ReadPoseGraph(path, &graph);
  ASSERT_TRUE(status.ok()) << status.message();
  const Comparison c =
      CompareIncrementalWithBatch(graph, 1, SmootherOptions(), batch_from_vertices);
  ExpectAgreement(c);
  ::testing::Test::RecordProperty("chi2", std::to_string(c.chi2_batch));
}

TEST(IncrementalVsBatchTest, M3500) { RealGraph("posegraph/M3500.g2o"); }
TEST(IncrementalVsBatchTest, Intel) { RealGraph("posegraph/intel.g2o"); }
TEST(IncrementalVsBatchTest, City10000) { RealGraph("posegraph/city10000.g2o"); }
TEST(IncrementalVsBatchTest, Csail) { RealGraph("posegraph/CSAIL.g2o"); }
// MIT: from composed odometry (which is also what the file's vertices hold) batch
// Gauss-Newton stops in a local minimum (chi2 769.7), while the incremental run reaches
// 39.60. So here the check is that the incremental result is a minimum a batch solve
// keeps (started from it, nothing moves) and that it is no worse than batch from odometry.
TEST(IncrementalVsBatchTest, Mit) {
  ANCHORMAP_REQUIRE_DATA(path, "posegraph/MIT.g2o");
  PoseGraph graph;
  ASSERT_TRUE(ReadPoseGraph(path, &graph).ok());
  const GraphReplay replay(graph, 1);
  Smoother incremental;
  for (int k = 0; k < replay.num_steps(); ++k) {
    ASSERT_TRUE(replay.AddStep(k, &incremental).ok());
    ASSERT_TRUE(incremental.Update().status.ok());
  }
  ASSERT_TRUE(incremental.BatchOptimize(kTightConvergence).status.ok());

  SmootherOptions options;
  options.batch_every_updates = 0;
  Smoother from_solution(options), from_odometry(options);
  ASSERT_TRUE(replay.AddAll(&from_odometry).ok());
  ASSERT_TRUE(from_odometry.BatchOptimize(kTightConvergence).status.ok());
  for (int64_t id = 0; id < replay.num_poses(); ++id) {
    ASSERT_TRUE(
        from_solution.AddPose(replay.KeyOf(id), incremental.FramePose(replay.KeyOf(id))).ok());
  }
  for (const GraphEdge& e : graph.edges) {
    ASSERT_TRUE(from_solution
                    .AddBetween(replay.KeyOf(e.from), replay.KeyOf(e.to), e.measured_T_from_to,
                                e.information.inverse())
                    .ok());
  }
  ASSERT_TRUE(from_solution.BatchOptimize(kTightConvergence).status.ok());
  double worst = 0.0;
  for (int64_t id = 0; id < replay.num_poses(); ++id) {
    const PoseKey key = replay.KeyOf(id);
    worst = std::max(
        worst,
        PoseError(incremental.FramePose(key), from_solution.FramePose(key)).cwiseAbs().maxCoeff());
  }
  EXPECT_LE(worst, 1e-6);
  EXPECT_NEAR(incremental.Chi2(), from_solution.Chi2(), 1e-6 * from_solution.Chi2());
  EXPECT_LE(incremental.Chi2(), from_odometry.Chi2());
}

TEST(IncrementalVsBatchTest, M3500ReachesTheIsamReferenceChi2) {
  ANCHORMAP_REQUIRE_DATA(path, "posegraph/M3500.g2o");
  PoseGraph graph;
  ASSERT_TRUE(ReadPoseGraph(path, &graph).ok());
  const GraphReplay replay(graph, 1);
  Smoother smoother;
  ASSERT_TRUE(replay.AddAll(&smoother).ok());
  ASSERT_TRUE(smoother.BatchOptimize().status.ok());
  // Kaess's iSAM 1.6 on the same edges: 6532.75 (SOURCES.md).
  EXPECT_NEAR(smoother.Chi2(), 6532.75, 0.01);
}

}  // namespace
}  // namespace anchormap
