#include "tools/render/merged_graph.h"

#include <filesystem>

#include <gtest/gtest.h>

#include "tests/testing/scratch.h"
#include "tools/render/testing_helpers.h"

namespace anchormap::render {
namespace {

TEST(MergedGraphTest, VerticesChainsAndEncounterEdges) {
  const std::string log = ::anchormap::testing::ScratchPath("graph.lcmlog");
  ASSERT_TRUE(testing::WriteTestServerLog(log).ok());
  ServerOutput output;
  ASSERT_TRUE(ReadServerOutput(log, ChannelNames{}, &output).ok());
  int skipped = -1;
  const PoseGraph graph = BuildMergedGraph(*output.map, &skipped);
  EXPECT_EQ(skipped, 0);
  ASSERT_EQ(graph.vertices.size(), 8u);  // 3 + 3 + 2 keyframes
  for (size_t i = 0; i < graph.vertices.size(); ++i)
    EXPECT_EQ(graph.vertices[i].id, static_cast<int64_t>(i));
  ASSERT_EQ(graph.edges.size(), 2u + 2u + 1u + 1u);  // chains + one encounter
  // R1's chain 0 -> 1: 4 m ahead.
  EXPECT_EQ(graph.edges[0].from, 0);
  EXPECT_EQ(graph.edges[0].to, 1);
  EXPECT_NEAR(graph.edges[0].measured_T_from_to.x(), 4.0, 1e-12);
  // The encounter: R1 keyframe 2 (vertex 2, at (8, 2) heading 0) to R2 keyframe 1
  // (vertex 4, at (10, 2) heading 1.57).
  const GraphEdge& encounter = graph.edges.back();
  EXPECT_EQ(encounter.from, 2);
  EXPECT_EQ(encounter.to, 4);
  EXPECT_NEAR(encounter.measured_T_from_to.x(), 2.0, 1e-12);
  EXPECT_NEAR(encounter.measured_T_from_to.y(), 0.0, 1e-12);
  EXPECT_NEAR(encounter.measured_T_from_to.theta(), 1.57, 1e-12);
  EXPECT_TRUE(encounter.information.isIdentity());

  // Written with graph_file and read back.
  const std::string path = ::anchormap::testing::ScratchPath("merged.g2o");
  ASSERT_TRUE(WritePoseGraph(path, graph, GraphFormat::kG2o).ok());
  PoseGraph back;
  ASSERT_TRUE(ReadPoseGraph(path, &back).ok());
  EXPECT_EQ(back.vertices.size(), 8u);
  EXPECT_EQ(back.edges.size(), 6u);
  EXPECT_NEAR(back.vertices[5].pose.y(), 8.0, 1e-9);
}

// Trajectory ids are unique per robot only: two robots' trajectories with one id are two
// chains, and a link names the robot's.
TEST(MergedGraphTest, TwoRobotsWithOneTrajectoryIdAreTwoChains) {
  MergedMap map;
  for (const char* robot : {"R1", "R2"}) {
    TrajectoryView trajectory;
    trajectory.key = {robot, 7};
    trajectory.anchored = true;
    trajectory.utimes = {1, 2};
    const double y = robot == std::string("R1") ? 0.0 : 5.0;
    trajectory.poses = {Pose2(0, y, 0), Pose2(1, y, 0)};
    map.trajectories.push_back(trajectory);
  }
  map.encounters.push_back({{"R2", 7}, 1, {"R1", 7}, 0});
  int skipped = -1;
  const PoseGraph graph = BuildMergedGraph(map, &skipped);
  EXPECT_EQ(skipped, 0);
  ASSERT_EQ(graph.vertices.size(), 4u);
  ASSERT_EQ(graph.edges.size(), 3u);  // two chains + the encounter
  const GraphEdge& encounter = graph.edges.back();
  EXPECT_EQ(encounter.from, 3);  // R2's keyframe 1 (R2's chain starts at vertex 2)
  EXPECT_EQ(encounter.to, 0);    // R1's keyframe 0
  EXPECT_NEAR(encounter.measured_T_from_to.x(), -1.0, 1e-12);
  EXPECT_NEAR(encounter.measured_T_from_to.y(), -5.0, 1e-12);
  EXPECT_EQ(map.FindPose({"R2", 7}, 0)->y(), 5.0);
  EXPECT_EQ(map.FindPose({"R1", 7}, 0)->y(), 0.0);
}

TEST(MergedGraphTest, UnknownLinksAreSkipped) {
  MergedMap map;
  TrajectoryView trajectory;
  trajectory.key.robot = "R1";
  trajectory.key.trajectory_id = 1;
  trajectory.utimes = {1, 2};
  trajectory.poses = {Pose2(), Pose2(1, 0, 0)};
  map.trajectories.push_back(trajectory);
  map.encounters.push_back({{"R1", 1}, 0, {"R1", 7}, 0});
  map.encounters.push_back({{"R1", 1}, 0, {"R2", 1}, 0});  // R2's id 1 is another trajectory
  int skipped = 0;
  const PoseGraph graph = BuildMergedGraph(map, &skipped);
  EXPECT_EQ(skipped, 2);
  EXPECT_EQ(graph.edges.size(), 1u);
}

}  // namespace
}  // namespace anchormap::render
