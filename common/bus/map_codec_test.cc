#include "common/bus/map_codec.h"

#include <gtest/gtest.h>

namespace anchormap {
namespace {

TEST(MapCodecTest, MergedMapRoundTrips) {
  MergedMap map;
  map.utime = 10;
  map.update = 3;
  MergedTrajectory t;
  t.robot = "R1";
  t.trajectory_id = 77;
  t.anchored = true;
  t.T_global_local = Pose2(1, 2, 0.5);
  t.pose_utimes = {100, 200};
  t.poses = {Pose2(1, 2, 0.5), Pose2(1.5, 2.1, 0.6)};
  map.trajectories.push_back(t);
  map.trajectories.push_back(MergedTrajectory{"R2", 78, false, Pose2(), {}, {}});
  map.encounters.push_back({"R1", 77, 1, "R2", 78, 0});
  const auto bytes = EncodeMergedMap(map);
  const auto decoded = DecodeMergedMap(bytes.data(), bytes.size());
  ASSERT_TRUE(decoded.ok()) << decoded.status().message();
  const MergedMap& d = *decoded;
  EXPECT_EQ(d.update, 3);
  ASSERT_EQ(d.trajectories.size(), 2u);
  EXPECT_TRUE(d.trajectories[0].anchored);
  EXPECT_FALSE(d.trajectories[1].anchored);
  EXPECT_EQ(d.trajectories[0].pose_utimes[1], 200);
  EXPECT_DOUBLE_EQ(d.trajectories[0].poses[1].x(), 1.5);
  EXPECT_DOUBLE_EQ(d.trajectories[0].T_global_local.theta(), 0.5);
  ASSERT_EQ(d.encounters.size(), 1u);
  EXPECT_EQ(d.encounters[0].trajectory_b, 78);
  EXPECT_EQ(d.encounters[0].robot_a, "R1");
  EXPECT_EQ(d.encounters[0].robot_b, "R2");
  EXPECT_EQ(d.encounters[0].index_a, 1);
  EXPECT_EQ(d.encounters[0].kind, ConstraintKind::kDirectEncounter);
}

TEST(MapCodecTest, EncounterLinksCarryTheirKind) {
  MergedMap map;
  map.trajectories.push_back(
      MergedTrajectory{"R1", 1, true, Pose2(), {1, 2}, {Pose2(), Pose2(1, 0, 0)}});
  map.trajectories.push_back(
      MergedTrajectory{"R2", 2, true, Pose2(), {1, 2}, {Pose2(), Pose2(1, 0, 0)}});
  map.encounters.push_back({"R1", 1, 0, "R2", 2, 0, ConstraintKind::kDirectEncounter});
  map.encounters.push_back({"R1", 1, 1, "R2", 2, 1, ConstraintKind::kScanEncounter});
  map.encounters.push_back({"R1", 1, 0, "R1", 1, 1, ConstraintKind::kLoopClosure});
  std::vector<uint8_t> bytes = EncodeMergedMap(map);
  const auto decoded = DecodeMergedMap(bytes.data(), bytes.size());
  ASSERT_TRUE(decoded.ok()) << decoded.status().message();
  ASSERT_EQ(decoded->encounters.size(), 3u);
  EXPECT_EQ(decoded->encounters[0].kind, ConstraintKind::kDirectEncounter);
  EXPECT_EQ(decoded->encounters[1].kind, ConstraintKind::kScanEncounter);
  EXPECT_EQ(decoded->encounters[2].kind, ConstraintKind::kLoopClosure);

  // An unknown kind (the last byte of the message is the last link's kind) is refused.
  bytes.back() = 7;
  const auto refused = DecodeMergedMap(bytes.data(), bytes.size());
  ASSERT_FALSE(refused.ok());
  EXPECT_EQ(refused.status().code(), ErrorCode::kInvalidValue);
}

TEST(MapCodecTest, AnchorCovariancesTileAndStatusRoundTrip) {
  AnchorCovariances anchors;
  anchors.update = 9;
  Eigen::Matrix3d cov;
  cov << 0.5, 0.1, 0.0, 0.1, 0.4, 0.02, 0.0, 0.02, 0.01;
  anchors.anchors.push_back({"R3", 5, Pose2(3, 4, 1), cov});
  auto bytes = EncodeAnchorCovariances(anchors);
  const auto a = DecodeAnchorCovariances(bytes.data(), bytes.size());
  ASSERT_TRUE(a.ok()) << a.status().message();
  ASSERT_EQ(a->anchors.size(), 1u);
  EXPECT_EQ(a->anchors[0].robot, "R3");
  EXPECT_DOUBLE_EQ(a->anchors[0].covariance(1, 2), 0.02);

  GridTile tile;
  tile.resolution_m = 0.1;
  tile.tile_x = -2;
  tile.tile_y = 3;
  tile.width = 4;
  tile.height = 2;
  tile.cells = {-1, 0, 100, 50, 1, 2, 3, 4};
  bytes = EncodeGridTile(tile);
  const auto g = DecodeGridTile(bytes.data(), bytes.size());
  ASSERT_TRUE(g.ok()) << g.status().message();
  EXPECT_EQ(g->cells, tile.cells);
  EXPECT_EQ(g->tile_x, -2);
  EXPECT_DOUBLE_EQ(g->resolution_m, 0.1);

  ServerStatus status;
  status.instance_id = 0x1234567890abcdefLL;
  status.kernel_drops = 17;
  status.num_robots = 3;
  status.keyframes = 400;
  status.rejections = {{"not_finite", 2}, {"duplicate_sequence", 1}};
  bytes = EncodeServerStatus(status);
  const auto s = DecodeServerStatus(bytes.data(), bytes.size());
  ASSERT_TRUE(s.ok()) << s.status().message();
  EXPECT_EQ(s->keyframes, 400);
  EXPECT_EQ(s->instance_id, 0x1234567890abcdefLL);
  EXPECT_EQ(s->kernel_drops, 17);
  ASSERT_EQ(s->rejections.size(), 2u);
  EXPECT_EQ(s->rejections[1].first, "duplicate_sequence");
  EXPECT_EQ(s->rejections[1].second, 1);
}

TEST(MapCodecTest, ForgedCountsAreRefused) {
  MergedMap map;
  map.trajectories.push_back(MergedTrajectory{"R1", 1, false, Pose2(), {1}, {Pose2()}});
  auto bytes = EncodeMergedMap(map);
  // num_trajectories after hash 8 + utime 8 + update 8.
  bytes[24] = 0x7f;
  const auto d = DecodeMergedMap(bytes.data(), bytes.size());
  EXPECT_FALSE(d.ok());
  EXPECT_EQ(d.status().code(), ErrorCode::kAbsurdSize);
}

TEST(MapCodecTest, NegativeInstanceIdAndDropCountsAreRefused) {
  ServerStatus status;
  status.instance_id = -5;
  auto bytes = EncodeServerStatus(status);
  auto s = DecodeServerStatus(bytes.data(), bytes.size());
  ASSERT_FALSE(s.ok());
  EXPECT_EQ(s.status().code(), ErrorCode::kInvalidValue);
  status.instance_id = 5;
  status.kernel_drops = -1;  // "cannot be seen": fine
  bytes = EncodeServerStatus(status);
  EXPECT_TRUE(DecodeServerStatus(bytes.data(), bytes.size()).ok());
  status.kernel_drops = -2;
  bytes = EncodeServerStatus(status);
  s = DecodeServerStatus(bytes.data(), bytes.size());
  ASSERT_FALSE(s.ok());
  EXPECT_EQ(s.status().code(), ErrorCode::kInvalidValue);
}

}  // namespace
}  // namespace anchormap
