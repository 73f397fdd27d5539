#include "tools/bench/area_graph_replay.h"

#include <cmath>

#include <gtest/gtest.h>

namespace anchormap {
namespace {

// Two robots driving the same 4 m x 4 m square, a keyframe every 0.5 m and second, five
// laps; robot 1 starts half a lap behind robot 0's start. One encounter joins them early.
void SquareLaps(std::vector<AreaReplayKeyframe>* keyframes, std::vector<AreaReplayLink>* links) {
  const int per_lap = 32;  // 16 m at 0.5 m
  for (int step = 0; step < 5 * per_lap; ++step) {
    for (int robot = 0; robot < 2; ++robot) {
      const int s = (step + robot * per_lap / 2) % per_lap;
      const int side = s / 8;
      const double along = 0.5 * (s % 8);
      const double x[4] = {along, 4.0, 4.0 - along, 0.0};
      const double y[4] = {0.0, along, 4.0, 4.0 - along};
      keyframes->push_back({1000000ll * step, robot, Pose2(x[side], y[side], side * M_PI / 2)});
    }
  }
  // Keyframe positions are 2 * step + robot; robot 1's step 0 is robot 0's step 16: the same
  // place. Joined at step 16.
  links->push_back({16 * 1000000ll + 1, 2 * 16, 1});
}

TEST(AreaGraphReplayTest,
     TheReducedGraphStopsGrowingOnceTheSquareIsCoveredWhileTheFullGraphDoesNot) {
  std::vector<AreaReplayKeyframe> keyframes;
  std::vector<AreaReplayLink> links;
  SquareLaps(&keyframes, &links);
  AreaReplayOptions options;
  options.rule = {1.0, 30.0 * M_PI / 180.0};
  std::vector<AreaReplayUpdate> full, reduced;
  AreaReplayAccuracy full_accuracy, reduced_accuracy;
  ASSERT_TRUE(ReplayAreaGraph(keyframes, links, 2, options, &full, &full_accuracy).ok());
  options.reduced = true;
  ASSERT_TRUE(ReplayAreaGraph(keyframes, links, 2, options, &reduced, &reduced_accuracy).ok());
  // The full graph has no loop closure here (one encounter), so five laps of odometry drift
  // (0.41 m); each fold is a match to a node of the first lap, a loop closed (0.019 m).
  EXPECT_GT(full_accuracy.after_batch_m, 0.2);
  EXPECT_LT(reduced_accuracy.after_batch_m, 0.05);
  EXPECT_LT(reduced_accuracy.after_updates_m, 0.05);
  ASSERT_EQ(full.size(), reduced.size());
  ASSERT_GE(full.size(), 300u);  // an update per 0.5 s of 160 s
  // Full: a pose per keyframe (320) and two anchors.
  EXPECT_EQ(full.back().variables, 322);
  // Reduced: the two robots cover the square once by 16 s (each half of it); from then on
  // every keyframe folds: 14 nodes (about one per 1.5 m of side and corner heading) and the
  // two anchors, the same at 20 s as after the five laps.
  const auto at = [&reduced](double data_s) {
    for (const AreaReplayUpdate& u : reduced) {
      if (u.data_s >= data_s) return u.variables;
    }
    return reduced.back().variables;
  };
  EXPECT_EQ(at(20.0), 16);
  EXPECT_EQ(reduced.back().variables, 16);
  // The factors still grow with time (a keyframe moving to another node adds one; those
  // between the same two nodes are not combined yet), if slower than the full graph's.
  EXPECT_GT(reduced.back().factors, 2 * reduced[39].factors);  // at 20 s
  EXPECT_LT(reduced.back().factors, full.back().factors / 2);
}

}  // namespace
}  // namespace anchormap
