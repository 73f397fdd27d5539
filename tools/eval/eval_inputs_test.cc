#include "tools/eval/eval_inputs.h"

#include <cmath>
#include <filesystem>
#include <fstream>

#include <unistd.h>

#include <gtest/gtest.h>

#include "bot_core/pose_t.hpp"
#include "common/bus/lcm_log.h"
#include "common/io/trajectory_file.h"
#include "tests/testing/scratch.h"

namespace anchormap {
namespace {

using ::anchormap::testing::ScratchPath;

trajectory_t MakeTrajectory(const std::string& robot, int64_t id, bool anchored,
                            const std::vector<std::array<double, 4>>& utime_x_y_theta) {
  trajectory_t t;
  t.robot = robot;
  t.trajectory_id = id;
  t.anchored = anchored;
  t.anchor[0] = t.anchor[1] = t.anchor[2] = 0.0;
  t.num_poses = static_cast<int32_t>(utime_x_y_theta.size());
  for (const auto& p : utime_x_y_theta) {
    t.pose_utimes.push_back(static_cast<int64_t>(p[0]));
    t.poses.push_back({p[1], p[2], p[3]});
  }
  return t;
}

merged_map_t MakeMap(int64_t update, std::vector<trajectory_t> trajectories,
                     std::vector<std::pair<int64_t, int64_t>> links) {
  merged_map_t map;
  map.utime = 1000 * update;
  map.update = update;
  map.trajectories = std::move(trajectories);
  map.num_trajectories = static_cast<int32_t>(map.trajectories.size());
  const auto robot_of = [&map](int64_t id) {
    for (const trajectory_t& t : map.trajectories) {
      if (t.trajectory_id == id) return t.robot;
    }
    return std::string("?");
  };
  for (const auto& [a, b] : links) {
    map.encounters.push_back({robot_of(a), a, 0, robot_of(b), b, 0, /*kind: direct*/ 0});
  }
  map.num_encounters = static_cast<int32_t>(map.encounters.size());
  return map;
}

TEST(ConvertMergedMapTest, GroupsFromEncounterLinksLargestFirst) {
  const merged_map_t map = MakeMap(
      5,
      {MakeTrajectory("R1", 11, true, {{{300, 1, 0, 0}}, {{100, 0, 0, 0}}}),
       MakeTrajectory("R2", 12, true, {{{100, 0, 0, 0}}}),
       MakeTrajectory("R3", 13, true, {{{100, 0, 0, 0}}, {{200, 0, 0, 0}}, {{300, 0, 0, 0}}}),
       MakeTrajectory("R4", 14, false, {{{100, NAN, 0, 0}}, {{200, 0, 0, 0}}})},
      {{11, 12}});
  MapEstimate estimate;
  ConvertMergedMap(map, &estimate);
  EXPECT_EQ(estimate.update, 5);
  ASSERT_EQ(estimate.trajectories.size(), 4u);
  EXPECT_EQ(estimate.num_groups, 2);
  EXPECT_EQ(estimate.trajectories[0].group, 0);  // R1 + R2: 3 poses
  EXPECT_EQ(estimate.trajectories[1].group, 0);
  EXPECT_EQ(estimate.trajectories[2].group, 1);  // R3 alone: 3 poses, listed later
  EXPECT_EQ(estimate.trajectories[3].group, -1);
  EXPECT_EQ(estimate.invalid_poses, 1);
  ASSERT_EQ(estimate.trajectories[3].poses.size(), 1u);
  // Sorted by time.
  EXPECT_EQ(estimate.trajectories[0].poses[0].utime, 100);
  EXPECT_EQ(estimate.trajectories[0].poses[1].pose.x(), 1.0);

  // Without any encounter link all anchored trajectories form one group.
  ConvertMergedMap(MakeMap(6, map.trajectories, {}), &estimate);
  EXPECT_EQ(estimate.num_groups, 1);
  EXPECT_EQ(estimate.trajectories[2].group, 0);
}

// Trajectory ids are unique per robot only (two agents may draw one id): a link joins the
// trajectories of the robots it names, never another robot's trajectory with that id.
TEST(ConvertMergedMapTest, TwoRobotsWithOneTrajectoryIdAreKeptApart) {
  merged_map_t map = MakeMap(3,
                             {MakeTrajectory("R1", 7, true, {{{100, 0, 0, 0}}, {{200, 1, 0, 0}}}),
                              MakeTrajectory("R2", 7, true, {{{100, 5, 0, 0}}}),
                              MakeTrajectory("R3", 8, true, {{{100, 9, 0, 0}}})},
                             {});
  map.encounters.push_back({"R2", 7, 0, "R3", 8, 0, /*kind: direct*/ 0});
  map.num_encounters = 1;
  MapEstimate estimate;
  ConvertMergedMap(map, &estimate);
  ASSERT_EQ(estimate.trajectories.size(), 3u);
  EXPECT_EQ(estimate.num_groups, 2);
  // R1 alone; R2 and R3 joined by the link that names them.
  EXPECT_NE(estimate.trajectories[0].group, estimate.trajectories[1].group);
  EXPECT_EQ(estimate.trajectories[1].group, estimate.trajectories[2].group);
  EXPECT_EQ(estimate.trajectories[0].robot, "R1");
  EXPECT_EQ(estimate.trajectories[1].robot, "R2");
  EXPECT_EQ(estimate.trajectories[1].trajectory_id, 7);
  EXPECT_EQ(estimate.trajectories[1].poses.at(0).pose.x(), 5.0);
}

Authenticator TestAuthenticator(const std::string& sender) {
  Result<Authenticator> authenticator = Authenticator::Create(
      *ParseKeyRing("fleet " + std::string(64, 'a')), AuthenticatorOptions{"", sender});
  EXPECT_TRUE(authenticator.ok());
  return std::move(*authenticator);
}

// anchormap-eval --key-file: a signed log's maps are read out of their envelopes; a map
// outside one (forged, or another server's) is refused and counted, not evaluated.
TEST(ReadMapEstimateTest, WithAKeyOnlyTheServersSignedMapsAreRead) {
  const std::string path = ScratchPath("am_eval_signed.lcmlog");
  Authenticator server = TestAuthenticator("server");
  {
    LcmLogWriter writer;
    ASSERT_TRUE(writer.Open(path).ok());
    const merged_map_t signed_map =
        MakeMap(5, {MakeTrajectory("R1", 1, false, {{{1, 2, 0, 0}}})}, {});
    std::vector<uint8_t> bytes(static_cast<size_t>(signed_map.getEncodedSize()));
    signed_map.encode(bytes.data(), 0, static_cast<int>(bytes.size()));
    const std::vector<uint8_t> sealed =
        server.Seal("ANCHORMAP_MERGED_MAP", bytes.data(), bytes.size());
    ASSERT_TRUE(writer.WriteRaw("ANCHORMAP_MERGED_MAP", 1, sealed.data(), sealed.size()).ok());
    // A later, unsigned map: the newest in the log, but no one with the key sent it.
    ASSERT_TRUE(writer
                    .Write("ANCHORMAP_MERGED_MAP", 2,
                           MakeMap(6, {MakeTrajectory("R1", 1, false, {{{1, 9, 0, 0}}})}, {}))
                    .ok());
  }
  Authenticator checking = TestAuthenticator("eval");
  MapEstimate estimate;
  ASSERT_TRUE(ReadMapEstimate(path, "ANCHORMAP_MERGED_MAP", "R1", &estimate, &checking).ok());
  EXPECT_EQ(estimate.update, 5);
  EXPECT_EQ(estimate.unauthenticated, 1);
  EXPECT_EQ(estimate.maps_seen, 2);
  ASSERT_EQ(estimate.trajectories.size(), 1u);
  EXPECT_EQ(estimate.trajectories[0].poses.at(0).pose.x(), 2.0);
  // Without the key the envelope does not decode as a map: the unsigned one is used.
  ASSERT_TRUE(ReadMapEstimate(path, "ANCHORMAP_MERGED_MAP", "R1", &estimate).ok());
  EXPECT_EQ(estimate.update, 6);
  EXPECT_EQ(estimate.undecodable, 1);
  EXPECT_EQ(estimate.unauthenticated, 0);
}

TEST(ReadMapEstimateTest, UsesTheLastDecodableMapAndCountsJunk) {
  const std::string path = ScratchPath("am_eval_map.lcmlog");
  {
    LcmLogWriter writer;
    ASSERT_TRUE(writer.Open(path).ok());
    ASSERT_TRUE(writer
                    .Write("ANCHORMAP_MERGED_MAP", 1,
                           MakeMap(1, {MakeTrajectory("R1", 1, false, {{{1, 0, 0, 0}}})}, {}))
                    .ok());
    ASSERT_TRUE(writer
                    .Write("ANCHORMAP_MERGED_MAP", 2,
                           MakeMap(2,
                                   {MakeTrajectory("R1", 1, false, {{{1, 0, 0, 0}}}),
                                    MakeTrajectory("R2", 2, false, {{{1, 0, 0, 0}}})},
                                   {}))
                    .ok());
    const char junk[5] = {1, 2, 3, 4, 5};
    ASSERT_TRUE(writer.WriteRaw("ANCHORMAP_MERGED_MAP", 3, junk, sizeof(junk)).ok());
    ASSERT_TRUE(writer.Write("OTHER", 4, bot_core::pose_t{}).ok());
  }
  EXPECT_TRUE(IsLcmLogFile(path));
  MapEstimate estimate;
  ASSERT_TRUE(ReadMapEstimate(path, "ANCHORMAP_MERGED_MAP", "R1", &estimate).ok());
  EXPECT_EQ(estimate.update, 2);
  EXPECT_EQ(estimate.maps_seen, 3);
  EXPECT_EQ(estimate.undecodable, 1);
  EXPECT_EQ(estimate.trajectories.size(), 2u);
  EXPECT_EQ(ReadMapEstimate(path, "NOPE", "R1", &estimate).message(),
            path +
                ": no complete merged map on channel NOPE or ANCHORMAP_MAP_HEADER + "
                "ANCHORMAP_MAP_CHUNKS (0 messages)");
  std::filesystem::remove(path);
}

TEST(ReadReferencesTest, GroundTruthPreferredQuaternionDecodedTumAccepted) {
  const std::string path = ScratchPath("am_eval_truth.lcmlog");
  {
    LcmLogWriter writer;
    ASSERT_TRUE(writer.Open(path).ok());
    for (int i = 0; i < 3; ++i) {
      bot_core::pose_t pose{};
      pose.utime = 100 * (3 - i);  // out of order on purpose
      pose.pos[0] = i;
      const double theta = -2.0 + i;
      pose.orientation[0] = std::cos(theta / 2);
      pose.orientation[3] = std::sin(theta / 2);
      ASSERT_TRUE(writer.Write("R1_GROUND_TRUTH", pose.utime, pose).ok());
      pose.pos[0] = 100 + i;
      ASSERT_TRUE(writer.Write("R1_REFERENCE", pose.utime, pose).ok());
      ASSERT_TRUE(writer.Write("R2_REFERENCE", pose.utime, pose).ok());
    }
    ASSERT_TRUE(writer.Write("R2_ODOMETRY", 1, bot_core::pose_t{}).ok());
  }
  ReferenceSet references;
  ASSERT_TRUE(ReadReferences(path, "R1", &references).ok());
  ASSERT_EQ(references.by_robot.size(), 2u);
  EXPECT_EQ(references.source_by_robot.at("R1"), "R1_GROUND_TRUTH");
  EXPECT_EQ(references.source_by_robot.at("R2"), "R2_REFERENCE");
  const StampedTrajectory& r1 = references.by_robot.at("R1");
  ASSERT_EQ(r1.size(), 3u);
  EXPECT_EQ(r1[0].utime, 100);
  EXPECT_EQ(r1[0].pose.x(), 2.0);
  EXPECT_NEAR(r1[0].pose.theta(), 0.0, 1e-12);
  EXPECT_NEAR(r1[2].pose.theta(), -2.0, 1e-12);
  EXPECT_EQ(references.by_robot.at("R2")[0].pose.x(), 102.0);

  const std::string tum = ScratchPath("am_eval_truth.txt");
  ASSERT_TRUE(WriteTrajectoryFile(tum, {{5, Pose2(1, 2, 0.5)}}).ok());
  EXPECT_FALSE(IsLcmLogFile(tum));
  ASSERT_TRUE(ReadReferences(tum, "R7", &references).ok());
  EXPECT_EQ(references.by_robot.at("R7")[0].pose.y(), 2.0);
  std::filesystem::remove(path);
  std::filesystem::remove(tum);
}

}  // namespace
}  // namespace anchormap
