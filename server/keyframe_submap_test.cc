#include "server/keyframe_submap.h"

#include <memory>

#include <gtest/gtest.h>

#include "server/mapping_server.h"
#include "tests/testing/straight_keyframes.h"

namespace anchormap {
namespace {

// True when the two references have the same grid and the same likelihood in every cell.
bool SameLikelihood(const ScanReference& a, const ScanReference& b) {
  const GridGeometry& ga = a.likelihood().geometry();
  const GridGeometry& gb = b.likelihood().geometry();
  if (ga.width != gb.width || ga.height != gb.height || ga.origin != gb.origin) return false;
  for (int iy = 0; iy < ga.height; ++iy) {
    for (int ix = 0; ix < ga.width; ++ix) {
      if (a.likelihood().Value(ix, iy) != b.likelihood().Value(ix, iy)) return false;
    }
  }
  return true;
}

TEST(KeyframeSubmapTest, ADrawingBuildsTheSubmapOfItsTimeAfterTheEstimateMoved) {
  MappingServerOptions options;
  options.loop_closures = false;
  options.scan_encounters = false;
  MappingServer server(options);
  for (int32_t seq = 0; seq < 20; ++seq) {
    ASSERT_TRUE(server.OnKeyframe(testing::StraightKeyframe("R1", 1, seq, 60)).ok());
  }
  server.Flush();
  const TrajectoryId t(0);
  const TrajectoryRecord* record = server.table().FindBySolverId(t);
  ASSERT_NE(record, nullptr);
  const PoseKey center{t, 10};
  const SubmapDrawing drawing = DrawKeyframeSubmap(*record, server.smoother(), center, 5, 15.0);
  EXPECT_EQ(drawing.T_center_keyframes.size(), 11u);
  EXPECT_GT(drawing.num_points, 0u);
  const ScanReferenceOptions reference_options;
  const std::unique_ptr<ScanReference> at_once =
      BuildKeyframeSubmap(*record, server.smoother(), center, 5, 15.0, reference_options);
  const std::unique_ptr<ScanReference> drawn =
      BuildKeyframeSubmap(*record, drawing, 15.0, reference_options);
  ASSERT_TRUE(at_once && drawn);
  EXPECT_TRUE(SameLikelihood(*at_once, *drawn));

  // A closure that bends the trajectory (keyframe 15 seen 1 m aside of where odometry puts
  // it): the submap's keyframes move, the drawing keeps their poses of its time.
  Smoother& smoother = server.mutable_smoother();
  ASSERT_TRUE(smoother
                  .AddBetween({t, 5}, {t, 15}, Pose2(10.0, 1.0, 0.2),
                              Eigen::Vector3d(1e-4, 1e-4, 1e-5).asDiagonal())
                  .ok());
  smoother.BatchOptimize();
  const std::unique_ptr<ScanReference> later =
      BuildKeyframeSubmap(*record, drawing, 15.0, reference_options);
  const std::unique_ptr<ScanReference> redrawn =
      BuildKeyframeSubmap(*record, server.smoother(), center, 5, 15.0, reference_options);
  ASSERT_TRUE(later && redrawn);
  EXPECT_TRUE(SameLikelihood(*drawn, *later));
  EXPECT_FALSE(SameLikelihood(*drawn, *redrawn));  // the estimate did move
}

TEST(KeyframeSubmapTest, AnEmptyDrawingBuildsNoReference) {
  MappingServerOptions options;
  options.loop_closures = false;
  options.scan_encounters = false;
  MappingServer server(options);
  for (int32_t seq = 0; seq < 5; ++seq) {
    ASSERT_TRUE(server.OnKeyframe(testing::StraightKeyframe("R1", 1, seq, 0)).ok());
  }
  server.Flush();
  const TrajectoryRecord* record = server.table().FindBySolverId(TrajectoryId(0));
  ASSERT_NE(record, nullptr);
  const SubmapDrawing drawing =
      DrawKeyframeSubmap(*record, server.smoother(), {TrajectoryId(0), 2}, 2, 15.0);
  EXPECT_EQ(drawing.num_points, 0u);
  EXPECT_EQ(BuildKeyframeSubmap(*record, drawing, 15.0, ScanReferenceOptions{}), nullptr);
}

}  // namespace
}  // namespace anchormap
