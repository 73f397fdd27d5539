#include "tools/viewer/node/viewer_node.h"

#include <gtest/gtest.h>

#include "common/bus/map_codec.h"

namespace anchormap::viewer {
namespace {

TEST(ViewerNodeTest, DecodesTheServersOutputsIntoTheState) {
  ViewerState state;
  ViewerNode node(ViewerChannels{}, &state);
  MergedMap map;
  map.update = 4;
  MergedTrajectory t;
  t.robot = "R1";
  t.trajectory_id = 3;
  t.poses = {Pose2(0, 0, 0), Pose2(1, 0, 0)};
  t.pose_utimes = {1, 2};
  map.trajectories.push_back(t);
  auto bytes = EncodeMergedMap(map);
  EXPECT_TRUE(node.OnMessage("ANCHORMAP_MERGED_MAP", bytes.data(), bytes.size(), 0));
  GridTile tile;
  tile.update = 4;
  tile.width = tile.height = 2;
  tile.cells = {0, 100, -1, 50};
  bytes = EncodeGridTile(tile);
  EXPECT_TRUE(node.OnMessage("ANCHORMAP_GRID_TILES", bytes.data(), bytes.size(), 0));
  ServerStatus status;
  status.update = 4;
  status.keyframes = 2;
  bytes = EncodeServerStatus(status);
  EXPECT_TRUE(node.OnMessage("ANCHORMAP_SERVER_STATUS", bytes.data(), bytes.size(), 0));
  AnchorCovariances anchors;
  anchors.update = 4;
  bytes = EncodeAnchorCovariances(anchors);
  EXPECT_TRUE(node.OnMessage("ANCHORMAP_ANCHOR_COVARIANCES", bytes.data(), bytes.size(), 0));
  EXPECT_EQ(state.num_trajectories(), 1u);
  EXPECT_EQ(state.num_keyframes(), 2);
  EXPECT_EQ(state.num_tiles(), 1u);
  EXPECT_EQ(state.Full()["status"]["keyframes"], 2);
  EXPECT_EQ(node.messages(), 4);
}

TEST(ViewerNodeTest, RefusesWhatDoesNotDecodeAndIgnoresOtherChannels) {
  ViewerState state;
  ViewerChannels channels;
  channels.merged_map = "MAP";
  ViewerNode node(channels, &state);
  MergedMap map;
  MergedTrajectory t;
  t.robot = "R1";
  t.poses = {Pose2(0, 0, 0)};
  t.pose_utimes = {1};
  map.trajectories.push_back(t);
  std::vector<uint8_t> bytes = EncodeMergedMap(map);
  EXPECT_FALSE(node.OnMessage("ANCHORMAP_MERGED_MAP", bytes.data(), bytes.size(), 0));
  std::vector<uint8_t> truncated(bytes.begin(), bytes.begin() + bytes.size() / 2);
  EXPECT_FALSE(node.OnMessage("MAP", truncated.data(), truncated.size(), 0));
  const uint8_t garbage[] = {1, 2, 3};
  EXPECT_FALSE(node.OnMessage("ANCHORMAP_GRID_TILES", garbage, sizeof(garbage), 0));
  EXPECT_EQ(node.rejections().total(), 2);
  EXPECT_EQ(state.num_trajectories(), 0u);
  EXPECT_TRUE(node.OnMessage("MAP", bytes.data(), bytes.size(), 0));
  EXPECT_EQ(state.num_trajectories(), 1u);
}

}  // namespace
}  // namespace anchormap::viewer
