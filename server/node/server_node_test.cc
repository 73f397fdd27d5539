#include "server/node/server_node.h"

#include <map>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "common/bus/codec.h"
#include "common/bus/map_codec.h"
#include "tests/testing/straight_keyframes.h"

namespace anchormap {
namespace {

Keyframe MakeKeyframe(const std::string& robot, int64_t trajectory, int32_t seq) {
  return testing::StraightKeyframe(robot, trajectory, seq, /*num_rays=*/3);
}

class ServerNodeTest : public ::testing::Test {
 protected:
  ServerNodeTest()
      : node_(ServerOptions{}, [this](const std::string& channel, const std::vector<uint8_t>& b) {
          published_[channel].push_back(b);
        }) {}

  bool Send(const std::string& channel, const std::vector<uint8_t>& bytes) {
    return node_.OnMessage(channel, bytes.data(), bytes.size());
  }

  ServerNode node_;
  std::map<std::string, std::vector<std::vector<uint8_t>>> published_;
};

TEST_F(ServerNodeTest, DecodedKeyframesAndEncountersReachTheMapThatIsPublished) {
  for (int32_t seq = 0; seq < 3; ++seq) {
    EXPECT_TRUE(Send(channels::kKeyframes, EncodeKeyframe(MakeKeyframe("R1", 11, seq))));
    EXPECT_TRUE(Send(channels::kKeyframes, EncodeKeyframe(MakeKeyframe("R2", 12, seq))));
  }
  Encounter e;
  e.utime = 2'000'000;
  e.observer = "R1";
  e.observer_trajectory_id = 11;
  e.observed = "R2";
  e.T_observer_observed = Pose2(0.0, 3.0, 0.0);
  e.covariance = Eigen::Vector3d(1e-2, 1e-2, 1e-3).asDiagonal();
  EXPECT_TRUE(Send(channels::kEncounters, EncodeEncounter(e)));
  node_.PublishAll();

  ASSERT_EQ(published_[channels::kMergedMap].size(), 1u);
  const auto& bytes = published_[channels::kMergedMap][0];
  const Result<MergedMap> map = DecodeMergedMap(bytes.data(), bytes.size());
  ASSERT_TRUE(map.ok()) << map.status().message();
  ASSERT_EQ(map->trajectories.size(), 2u);
  EXPECT_EQ(map->trajectories[1].robot, "R2");
  EXPECT_EQ(map->trajectories[1].poses.size(), 3u);
  EXPECT_TRUE(map->trajectories[1].anchored);
  ASSERT_EQ(map->encounters.size(), 1u);
  // R2's pose 1 stands 3 m to the left of R1's pose 1.
  EXPECT_NEAR(map->trajectories[1].poses[1].y(), 3.0, 1e-6);

  const auto& covariance_bytes = published_[channels::kAnchorCovariances].at(0);
  const Result<AnchorCovariances> covariances =
      DecodeAnchorCovariances(covariance_bytes.data(), covariance_bytes.size());
  ASSERT_TRUE(covariances.ok());
  EXPECT_EQ(covariances->anchors.size(), 2u);
  EXPECT_FALSE(published_[channels::kGridTiles].empty());

  const auto& status_bytes = published_[channels::kServerStatus].at(0);
  const Result<ServerStatus> status = DecodeServerStatus(status_bytes.data(), status_bytes.size());
  ASSERT_TRUE(status.ok());
  EXPECT_EQ(status->keyframes, 6);
  EXPECT_EQ(status->num_anchored, 2);
}

TEST_F(ServerNodeTest, UndecodableBytesAreCountedByReasonOnTheirChannel) {
  const std::vector<uint8_t> garbage = {1, 2, 3};
  EXPECT_TRUE(Send(channels::kKeyframes, garbage));
  Keyframe bad = MakeKeyframe("R1", 11, 1);
  bad.T_previous_this_covariance(0, 0) = -1.0;
  EXPECT_TRUE(Send(channels::kKeyframes, EncodeKeyframe(bad)));
  EXPECT_TRUE(Send(channels::kEncounters, garbage));
  EXPECT_FALSE(Send("SOMEONE_ELSES_CHANNEL", garbage));  // not ours: ignored, not counted
  const RejectCounter& rejects = node_.server().rejects();
  EXPECT_EQ(rejects.count(ErrorCode::kDecodeFailed), 2);
  EXPECT_EQ(rejects.count(ErrorCode::kCovarianceNotSpd), 1);
  EXPECT_EQ(rejects.total(), 3);
  EXPECT_EQ(node_.server().stats().keyframes_received, 0);
}

}  // namespace
}  // namespace anchormap
