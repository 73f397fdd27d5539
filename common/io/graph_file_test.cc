#include "common/io/graph_file.h"

#include <filesystem>

#include <gtest/gtest.h>

#include "tests/testing/data_path.h"
#include "tests/testing/scratch.h"

namespace anchormap {
namespace {

const char* kSmallG2o =
    "# a comment\n"
    "VERTEX_SE2 0 0 0 0\n"
    "VERTEX_SE2 1 1 0 0.5\n"
    "\n"
    "EDGE_SE2 0 1 1 0 0.5 100 1 2 200 3 300\n"
    "FIX 0\n";

TEST(GraphFileTest, ParsesG2o) {
  PoseGraph graph;
  ASSERT_TRUE(ParsePoseGraph(kSmallG2o, "small.g2o", &graph).ok());
  ASSERT_EQ(graph.vertices.size(), 2u);
  ASSERT_EQ(graph.edges.size(), 1u);
  EXPECT_EQ(graph.vertices[1].pose.theta(), 0.5);
  const Eigen::Matrix3d& I = graph.edges[0].information;
  EXPECT_EQ(I(0, 0), 100);
  EXPECT_EQ(I(0, 1), 1);
  EXPECT_EQ(I(2, 0), 2);
  EXPECT_EQ(I(1, 1), 200);
  EXPECT_EQ(I(2, 1), 3);
  EXPECT_EQ(I(2, 2), 300);
}

TEST(GraphFileTest, ParsesToroInformationOrder) {
  PoseGraph graph;
  // TORO: I11 I12 I22 I33 I13 I23
  ASSERT_TRUE(
      ParsePoseGraph("VERTEX2 0 0 0 0\nEDGE2 0 1 1 2 0.1 100 1 200 300 2 3\n", "t", &graph).ok());
  const Eigen::Matrix3d& I = graph.edges[0].information;
  EXPECT_EQ(I(0, 0), 100);
  EXPECT_EQ(I(0, 1), 1);
  EXPECT_EQ(I(1, 1), 200);
  EXPECT_EQ(I(2, 2), 300);
  EXPECT_EQ(I(0, 2), 2);
  EXPECT_EQ(I(1, 2), 3);
}

TEST(GraphFileTest, RoundTripsBothFormats) {
  PoseGraph graph;
  ASSERT_TRUE(ParsePoseGraph(kSmallG2o, "small.g2o", &graph).ok());
  for (GraphFormat format : {GraphFormat::kG2o, GraphFormat::kToro}) {
    const std::string path = ::anchormap::testing::ScratchPath("graph_roundtrip.txt");
    ASSERT_TRUE(WritePoseGraph(path, graph, format).ok());
    PoseGraph back;
    ASSERT_TRUE(ReadPoseGraph(path, &back).ok());
    ASSERT_EQ(back.edges.size(), 1u);
    EXPECT_EQ(back.edges[0].information, graph.edges[0].information);
    EXPECT_EQ(back.vertices[1].pose.x(), 1.0);
    std::filesystem::remove(path);
  }
}

TEST(GraphFileTest, MalformedLinesNameFileLineAndReason) {
  PoseGraph graph;
  struct Case {
    const char* text;
    const char* message;
  };
  const Case cases[] = {
      {"VERTEX_SE2 0 0 0 0\nEDGE_SE2 0 1 1 0 0\n",
       "g.g2o:2: EDGE_SE2: expected 9 numbers, found 3"},
      {"VERTEX_SE2 0 0 abc 0\n", "g.g2o:1: VERTEX_SE2: 'abc' is not a number"},
      {"VERTEX_SE2 -3 0 0 0\n",
       "g.g2o:1: VERTEX_SE2: '-3' is not a vertex id (a non-negative integer)"},
      {"\n\nEDGE_SE2 0 1 1 0 0 1 0 0 1 0 -1\n",
       "g.g2o:3: EDGE_SE2: information matrix is not positive definite"},
      {"VERTEX_SE2 0 0 nan 0\n", "g.g2o:1: VERTEX_SE2: value 'nan' is not finite"},
      {"VERTEX_XY 0 1 2\n",
       "g.g2o:1: unknown element 'VERTEX_XY' (a 2D pose graph has VERTEX_SE2/EDGE_SE2 or "
       "VERTEX2/EDGE2 lines)"},
      {"EDGE_SE2 2 2 1 0 0 1 0 0 1 0 1\n", "g.g2o:1: EDGE_SE2: edge from a vertex to itself"},
      {"VERTEX_SE2 0 0 0 0 7\n", "g.g2o:1: VERTEX_SE2: unexpected trailing '7'"},
  };
  for (const Case& c : cases) {
    const Status status = ParsePoseGraph(c.text, "g.g2o", &graph);
    ASSERT_FALSE(status.ok()) << c.text;
    EXPECT_EQ(status.message(), c.message);
  }
  EXPECT_EQ(ReadPoseGraph("/nonexistent/x.g2o", &graph).message(),
            "/nonexistent/x.g2o: cannot open");
}

TEST(GraphFileTest, InitialGuessComposesOdometry) {
  PoseGraph graph;
  ASSERT_TRUE(ParsePoseGraph("EDGE_SE2 0 1 1 0 1.5707963267948966 1 0 0 1 0 1\n"
                             "EDGE_SE2 1 2 1 0 0 1 0 0 1 0 1\n"
                             "EDGE_SE2 0 2 0 0 0 1 0 0 1 0 1\n",
                             "o", &graph)
                  .ok());
  std::vector<Pose2> poses;
  ASSERT_TRUE(InitialGuessFromOdometry(graph, &poses).ok());
  ASSERT_EQ(poses.size(), 3u);
  EXPECT_NEAR(poses[2].x(), 1.0, 1e-12);
  EXPECT_NEAR(poses[2].y(), 1.0, 1e-12);
  graph.edges.erase(graph.edges.begin());
  EXPECT_EQ(InitialGuessFromOdometry(graph, &poses).message(), "no odometry edge 0 -> 1");
}

TEST(GraphFileTest, ReadsRealGraphs) {
  struct Expected {
    const char* file;
    size_t vertices, edges;
  };
  for (const Expected& e :
       {Expected{"posegraph/M3500.g2o", 0, 5598}, Expected{"posegraph/intel.g2o", 1728, 2512},
        Expected{"posegraph/MIT.g2o", 808, 827}}) {
    const std::string path = testing::DataFile(e.file);
    if (path.empty()) GTEST_SKIP() << e.file << " not found in " << testing::DataDir();
    PoseGraph graph;
    const Status status = ReadPoseGraph(path, &graph);
    ASSERT_TRUE(status.ok()) << status.message();
    EXPECT_EQ(graph.vertices.size(), e.vertices) << e.file;
    EXPECT_EQ(graph.edges.size(), e.edges) << e.file;
  }
}

}  // namespace
}  // namespace anchormap
