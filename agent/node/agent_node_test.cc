#include "agent/node/agent_node.h"

#include <map>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "common/bus/codec.h"
#include "common/bus/delivery_codec.h"
#include "tests/testing/scratch.h"

namespace anchormap {
namespace {

class AgentNodeTest : public ::testing::Test {
 protected:
  AgentNodeTest()
      : node_(Options(), [this](const std::string& channel, const std::vector<uint8_t>& b) {
          published_[channel].push_back(b);
        }) {}

  static AgentNodeOptions Options() {
    AgentNodeOptions options;
    options.agent.robot = "R1";
    options.agent.trajectory_id = 77;
    options.agent.max_range_m = 25.0;
    options.agent.sensor_x_m = 0.2;
    options.agent.keyframer.max_distance_m = 0.45;
    options.agent.keyframer.max_interval_s = 0;
    return options;
  }

  bool Send(const std::string& channel, const std::vector<uint8_t>& bytes) {
    return node_.OnMessage(channel, bytes.data(), bytes.size());
  }

  // Drives 1 m/s along x for `seconds`: odometry at 50 Hz, a 3-beam scan at 10 Hz.
  void Drive(double seconds) {
    for (int64_t t = 0; t <= static_cast<int64_t>(seconds * 1e6); t += 20'000) {
      EXPECT_TRUE(Send("R1_ODOMETRY", EncodeOdometry({t, Pose2(1e-6 * t, 0, 0)})));
      if (t % 100'000 == 20'000) {
        LaserScan scan;
        scan.utime = t - 15'000;
        scan.radstep = 0.1f;
        scan.ranges = {1.0f, 2.0f, 3.0f};
        EXPECT_TRUE(Send("R1_LASER", EncodeLaser(scan)));
      }
    }
  }

  std::vector<Keyframe> Keyframes() const {
    std::vector<Keyframe> out;
    if (!published_.count(channels::kKeyframes)) return out;
    for (const auto& bytes : published_.at(channels::kKeyframes)) {
      Result<Keyframe> k = DecodeKeyframe(bytes.data(), bytes.size());
      EXPECT_TRUE(k.ok()) << k.status().message();
      if (k.ok()) out.push_back(std::move(*k));
    }
    return out;
  }

  AgentNode node_;
  std::map<std::string, std::vector<std::vector<uint8_t>>> published_;
};

TEST_F(AgentNodeTest, ChannelsDeriveFromTheRobotName) {
  EXPECT_EQ(node_.InputChannels(),
            (std::vector<std::string>{"R1_ODOMETRY", "R1_LASER", "R1_LASER_MOUNT", "R1_ENCOUNTER",
                                      channels::kEncounters, channels::kAcks,
                                      channels::kResendRequests}));
}

TEST_F(AgentNodeTest, OdometryAndScansBecomeKeyframesWithTheMountingPoseAndRangeLimit) {
  Drive(2.0);
  const std::vector<Keyframe> keyframes = Keyframes();
  ASSERT_GE(keyframes.size(), 4u);
  for (size_t i = 0; i < keyframes.size(); ++i) {
    EXPECT_EQ(keyframes[i].robot, "R1");
    EXPECT_EQ(keyframes[i].trajectory_id, 77);
    EXPECT_EQ(keyframes[i].seq, static_cast<int32_t>(i));
    // Set once by the agent from its options: the wire's laser carries neither.
    EXPECT_DOUBLE_EQ(keyframes[i].scan.T_body_sensor.x(), 0.2);
    EXPECT_FLOAT_EQ(keyframes[i].scan.max_range, 25.0f);
    EXPECT_EQ(keyframes[i].scan.ranges, (std::vector<float>{1.0f, 2.0f, 3.0f}));
  }
  // Keyframe 2 is 0.5 m past keyframe 1 (one scan every 0.1 m, threshold 0.45 m).
  EXPECT_NEAR(keyframes[2].T_previous_this.x(), 0.5, 1e-9);
  EXPECT_NEAR(keyframes[2].T_local_pose.x() - keyframes[1].T_local_pose.x(), 0.5, 1e-9);
  EXPECT_EQ(node_.rejects().total(), 0);
}

TEST_F(AgentNodeTest, LaserMountMessageReplacesTheSensorOptions) {
  // As anchormap-import-carmen writes it: the laser's pose on the body, before the data.
  EXPECT_TRUE(Send("R1_LASER_MOUNT", EncodeOdometry({0, Pose2(-0.04, 0.01, 0.02)})));
  Drive(1.0);
  const std::vector<Keyframe> keyframes = Keyframes();
  ASSERT_GE(keyframes.size(), 2u);
  for (const Keyframe& k : keyframes) {
    EXPECT_DOUBLE_EQ(k.scan.T_body_sensor.x(), -0.04);
    EXPECT_DOUBLE_EQ(k.scan.T_body_sensor.y(), 0.01);
    EXPECT_NEAR(k.scan.T_body_sensor.theta(), 0.02, 1e-12);
  }
  const std::vector<uint8_t> garbage = {1, 2};
  EXPECT_TRUE(Send("R1_LASER_MOUNT", garbage));
  EXPECT_EQ(node_.rejects().count(ErrorCode::kDecodeFailed), 1);
  EXPECT_DOUBLE_EQ(node_.agent().sensor_mounting().x(), -0.04);
}

TEST_F(AgentNodeTest, StatusLineShowsScanMatchingAndItsCpu) {
  Drive(1.0);
  const std::string line = node_.StatusLine();
  // 3-beam scans are too few points to match: every one is odometry.
  EXPECT_NE(line.find("scan matching: matched 0/10 odometry 10"), std::string::npos) << line;
  EXPECT_NE(line.find("ms/scan"), std::string::npos) << line;
}

TEST_F(AgentNodeTest, BadInputIsCountedByReasonAndOthersRelaysAreNotOurs) {
  const std::vector<uint8_t> garbage = {9, 9, 9};
  EXPECT_TRUE(Send("R1_ODOMETRY", garbage));
  EXPECT_TRUE(Send("R1_LASER", garbage));
  EXPECT_TRUE(Send("ANCHORMAP_ENCOUNTERS", garbage));  // the server counts those
  EXPECT_FALSE(Send("R2_ODOMETRY", garbage));
  EXPECT_TRUE(Send("R1_ODOMETRY", EncodeOdometry({100, Pose2()})));
  EXPECT_TRUE(Send("R1_ODOMETRY", EncodeOdometry({100, Pose2()})));  // not after the last
  Encounter wrong;
  wrong.observer = "R2";  // on R1's channel
  wrong.observed = "R3";
  wrong.covariance = Eigen::Matrix3d::Identity();
  EXPECT_TRUE(Send("R1_ENCOUNTER", EncodeEncounter(wrong)));
  EXPECT_EQ(node_.rejects().count(ErrorCode::kDecodeFailed), 2);
  EXPECT_EQ(node_.rejects().count(ErrorCode::kOutOfOrder), 1);
  EXPECT_EQ(node_.rejects().count(ErrorCode::kWrongRobot), 1);
  EXPECT_EQ(node_.rejects().total(), 4);
}

TEST_F(AgentNodeTest, OwnEncountersAreRelayedWithTheTrajectoryAndForceAKeyframe) {
  Drive(1.0);
  const size_t before = Keyframes().size();
  Encounter seen;
  seen.utime = 1'050'000;
  seen.observer = "R1";
  seen.observed = "R2";
  seen.T_observer_observed = Pose2(1.0, 0.0, 0.0);
  seen.covariance = Eigen::Matrix3d::Identity() * 0.01;
  EXPECT_TRUE(Send("R1_ENCOUNTER", EncodeEncounter(seen)));
  ASSERT_EQ(published_[channels::kEncounters].size(), 1u);
  const auto& bytes = published_[channels::kEncounters][0];
  const Result<Encounter> relayed = DecodeEncounter(bytes.data(), bytes.size());
  ASSERT_TRUE(relayed.ok());
  EXPECT_EQ(relayed->observer_trajectory_id, 77);
  // The next scan (t = 1.105 s, only 0.1 m on) becomes a keyframe for the encounter.
  EXPECT_TRUE(Send("R1_ODOMETRY", EncodeOdometry({1'120'000, Pose2(1.12, 0, 0)})));
  LaserScan scan;
  scan.utime = 1'105'000;
  scan.radstep = 0.1f;
  scan.ranges = {1.0f, 2.0f, 3.0f};
  EXPECT_TRUE(Send("R1_LASER", EncodeLaser(scan)));
  EXPECT_EQ(Keyframes().size(), before + 1);
  EXPECT_EQ(Keyframes().back().utime, 1'105'000);
}

// The server is away: with a 1 KiB memory bound the agent's outbox spills what it
// published to a file; when the server asks for everything, all of it goes out again, in
// order and byte for byte, and its acknowledgement empties outbox and file.
TEST(AgentNodeSpillTest, ASmallBoundSpillsAndEverythingIsDeliveredInOrderAfterwards) {
  AgentNodeOptions options;
  options.agent.robot = "R1";
  options.agent.trajectory_id = 5;
  options.agent.keyframer.max_distance_m = 0.45;
  options.agent.keyframer.max_interval_s = 0;
  options.agent.scan_matching.enabled = false;
  options.outbox.max_bytes = 1024;
  options.outbox.spill_dir = testing::ScratchDir().string();
  std::vector<std::vector<uint8_t>> sent;
  AgentNode node(options, [&sent](const std::string& channel, const std::vector<uint8_t>& b) {
    if (channel == channels::kKeyframes) sent.push_back(b);
  });
  for (int64_t t = 0; t <= 30'000'000; t += 20'000) {
    const auto odometry = EncodeOdometry({t, Pose2(1e-6 * t, 0, 0)});
    node.OnMessage("R1_ODOMETRY", odometry.data(), odometry.size());
    if (t % 100'000 == 20'000) {
      LaserScan scan;
      scan.utime = t - 15'000;
      scan.radstep = 0.01f;
      scan.ranges.assign(90, 4.0f);
      const auto laser = EncodeLaser(scan);
      node.OnMessage("R1_LASER", laser.data(), laser.size());
    }
  }
  const size_t published = sent.size();
  ASSERT_GE(published, 50u);
  EXPECT_EQ(node.outbox().size(), published);
  EXPECT_LE(node.outbox().bytes(), 1024u);
  EXPECT_GE(node.outbox().spilled_entries(), published - 3);
  EXPECT_EQ(node.outbox().stats().dropped, 0);
  EXPECT_EQ(node.rejects().total(), 0) << node.rejects().Summary();

  ResendRequest request;
  request.robot = "R1";
  request.trajectory_id = 5;
  request.ranges = {{StreamKind::kKeyframes, 0, static_cast<int32_t>(published) - 1}};
  auto bytes = EncodeResendRequest(request);
  node.OnMessage(channels::kResendRequests, bytes.data(), bytes.size());
  ASSERT_EQ(sent.size(), 2 * published);
  for (size_t i = 0; i < published; ++i) {
    ASSERT_EQ(sent[published + i], sent[i]) << "keyframe " << i;
    EXPECT_EQ(DecodeKeyframe(sent[published + i].data(), sent[published + i].size())->seq,
              static_cast<int32_t>(i));
  }
  DeliveryAck ack;
  ack.robot = "R1";
  ack.trajectory_id = 5;
  ack.keyframes_next = static_cast<int32_t>(published);
  bytes = EncodeDeliveryAck(ack);
  node.OnMessage(channels::kAcks, bytes.data(), bytes.size());
  EXPECT_EQ(node.outbox().size(), 0u);
  EXPECT_EQ(node.outbox().spill_file_bytes(), 0);
}

}  // namespace
}  // namespace anchormap
