#include "tools/viewer/node/viewer_node.h"

#include <gtest/gtest.h>

#include "common/bus/authenticator.h"
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

Authenticator MakeAuthenticator(const std::string& key_line, const std::string& sender) {
  Result<KeyRing> keys = ParseKeyRing(key_line);
  EXPECT_TRUE(keys.ok()) << keys.status().message();
  AuthenticatorOptions options;
  options.sender = sender;
  Result<Authenticator> authenticator = Authenticator::Create(std::move(*keys), options);
  EXPECT_TRUE(authenticator.ok()) << authenticator.status().message();
  return std::move(*authenticator);
}

// anchormap-viewer --key-file: only the server's signed outputs are drawn; unsigned,
// forged and replayed ones are refused and counted by reason.
TEST(ViewerNodeTest, WithAKeyOnlyTheServersSignedOutputsAreDrawn) {
  const std::string fleet = "fleet " + std::string(64, 'a') + "\n";
  const std::string other = "fleet " + std::string(64, 'b') + "\n";  // same id, wrong secret
  Authenticator server = MakeAuthenticator(fleet, "server");
  Authenticator forger = MakeAuthenticator(other, "server");
  ViewerState state;
  ViewerNode node(ViewerChannels{}, &state);
  node.RequireAuthentication(MakeAuthenticator(fleet, "viewer"));

  ServerStatus status;
  status.update = 7;
  status.keyframes = 11;
  const std::vector<uint8_t> plain = EncodeServerStatus(status);
  const std::string channel = "ANCHORMAP_SERVER_STATUS";
  EXPECT_FALSE(node.OnMessage(channel, plain.data(), plain.size(), 0));
  const std::vector<uint8_t> forged = forger.Seal(channel, plain.data(), plain.size());
  EXPECT_FALSE(node.OnMessage(channel, forged.data(), forged.size(), 0));
  // Signed for another channel: the tag covers the channel.
  const std::vector<uint8_t> elsewhere =
      server.Seal("ANCHORMAP_MERGED_MAP", plain.data(), plain.size());
  EXPECT_FALSE(node.OnMessage(channel, elsewhere.data(), elsewhere.size(), 0));
  EXPECT_FALSE(state.Full()["status"].contains("keyframes") &&
               state.Full()["status"]["keyframes"] == 11);

  const std::vector<uint8_t> sealed = server.Seal(channel, plain.data(), plain.size());
  EXPECT_TRUE(node.OnMessage(channel, sealed.data(), sealed.size(), 0));
  EXPECT_EQ(state.Full()["status"]["keyframes"], 11);
  EXPECT_FALSE(node.OnMessage(channel, sealed.data(), sealed.size(), 0));  // replayed

  EXPECT_EQ(node.rejections().count(ErrorCode::kUnsigned), 1);
  EXPECT_EQ(node.rejections().count(ErrorCode::kBadTag), 2);
  EXPECT_EQ(node.rejections().count(ErrorCode::kReplay), 1);
  EXPECT_EQ(node.rejections().total(), 4);
  EXPECT_EQ(node.messages(), 5);

  // A viewer without the key cannot read a signing server's outputs: refused, not drawn.
  ViewerState keyless_state;
  ViewerNode keyless(ViewerChannels{}, &keyless_state);
  const std::vector<uint8_t> signed_again = server.Seal(channel, plain.data(), plain.size());
  EXPECT_FALSE(keyless.OnMessage(channel, signed_again.data(), signed_again.size(), 0));
  EXPECT_EQ(keyless.rejections().count(ErrorCode::kDecodeFailed), 1);
}

}  // namespace
}  // namespace anchormap::viewer
