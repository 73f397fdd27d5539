#include "server/keyframe_submap.h"

#include <memory>
#include <vector>

#include <gtest/gtest.h>

#include "server/mapping_server.h"
#include "tests/testing/straight_keyframes.h"

namespace anchormap {
namespace {

// True when the two references have the same grid and the same likelihood in every cell.
// A server with neither loop closures nor scan encounters (the tests draw submaps by hand).
MappingServerOptions WithoutScanSources() {
  MappingServerOptions options;
  options.loop_closures = false;
  options.scan_encounters = false;
  return options;
}

// `keyframes` keyframes of robot R1, 1 m apart along x with `num_rays` rays each, solved.
void AddStraightTrack(MappingServer* server, int32_t keyframes, int num_rays) {
  for (int32_t seq = 0; seq < keyframes; ++seq) {
    ASSERT_TRUE(server->OnKeyframe(testing::StraightKeyframe("R1", 1, seq, num_rays)).ok());
  }
  server->Flush();
}

TEST(KeyframeSubmapTest, ADrawingBuildsTheSubmapOfItsTimeAfterTheEstimateMoved) {
  MappingServer server(WithoutScanSources());
  AddStraightTrack(&server, 20, 60);
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
  EXPECT_TRUE(at_once->SameLikelihood(*drawn));

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
  EXPECT_TRUE(drawn->SameLikelihood(*later));
  EXPECT_FALSE(drawn->SameLikelihood(*redrawn));  // the estimate did move
}

TEST(KeyframeSubmapTest, AnEmptyDrawingBuildsNoReference) {
  MappingServer server(WithoutScanSources());
  AddStraightTrack(&server, 5, 0);
  const TrajectoryRecord* record = server.table().FindBySolverId(TrajectoryId(0));
  ASSERT_NE(record, nullptr);
  const SubmapDrawing drawing =
      DrawKeyframeSubmap(*record, server.smoother(), {TrajectoryId(0), 2}, 2, 15.0);
  EXPECT_EQ(drawing.num_points, 0u);
  EXPECT_EQ(BuildKeyframeSubmap(*record, drawing, 15.0, ScanReferenceOptions{}), nullptr);
}

// The indices of a drawing's keyframes, in its order.
std::vector<int> Indices(const SubmapDrawing& drawing) {
  std::vector<int> indices;
  for (const auto& [index, pose] : drawing.T_center_keyframes) indices.push_back(index);
  return indices;
}

TEST(KeyframeSubmapTest, ASubmapByPlaceAddsTheKeyframesNearestToAPlaceFarFromItsCentre) {
  MappingServer server(WithoutScanSources());
  AddStraightTrack(&server, 30, 60);
  const TrajectoryId t(0);
  const TrajectoryRecord* record = server.table().FindBySolverId(t);
  ASSERT_NE(record, nullptr);
  const PoseKey center{t, 5};
  PlaceSubmapOptions place;
  place.keep_first = 4;
  place.keep_last = 6;
  place.radius_m = 3.5;  // keyframes 17-23 around x = 15 (keyframe 20) in the centre's frame
  place.last_index = 25;
  place.max_keyframes = 4;
  const Eigen::Vector2d at(15.0, 0.0);
  SubmapDrawing drawing =
      DrawKeyframeSubmapNear(*record, server.smoother(), center, at, place, 15.0);
  // The kept ones, then the 4 nearest to the place (on ties the lower index): 20, 19, 21, 18.
  EXPECT_EQ(Indices(drawing), (std::vector<int>{4, 5, 6, 18, 19, 20, 21}));
  EXPECT_NEAR(drawing.T_center_keyframes[3].second.x(), 13.0, 1e-6);
  EXPECT_GT(drawing.num_points, 0u);

  // Nothing past last_index (the query's own recent keyframes stand at the place too).
  place.last_index = 19;
  drawing = DrawKeyframeSubmapNear(*record, server.smoother(), center, at, place, 15.0);
  EXPECT_EQ(Indices(drawing), (std::vector<int>{4, 5, 6, 17, 18, 19}));

  // A keyframe within the spacing of a kept one (same heading) adds nothing: every second.
  place.last_index = 25;
  place.spacing_m = 1.5;
  place.spacing_rad = 0.5;
  drawing = DrawKeyframeSubmapNear(*record, server.smoother(), center, at, place, 15.0);
  EXPECT_EQ(Indices(drawing), (std::vector<int>{4, 5, 6, 18, 20, 22}));
}

}  // namespace
}  // namespace anchormap
