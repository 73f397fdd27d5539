#include "server/trajectory_table.h"

#include <gtest/gtest.h>

namespace anchormap {
namespace {

// Keyframe `seq` of a robot driving along x at 1 m/s, one keyframe every 0.5 s.
Keyframe MakeKeyframe(const std::string& robot, int64_t trajectory, int32_t seq,
                      int64_t start_utime = 0) {
  Keyframe k;
  k.robot = robot;
  k.trajectory_id = trajectory;
  k.seq = seq;
  k.utime = start_utime + seq * 500'000;
  k.T_local_pose = Pose2(0.5 * seq, 0.0, 0.0);
  if (seq > 0) {
    k.T_previous_this = Pose2(0.5, 0.0, 0.0);
    k.T_previous_this_covariance = Eigen::Vector3d(1e-3, 1e-3, 1e-4).asDiagonal();
  }
  k.scan.ranges = {1.0f};
  return k;
}

TEST(TrajectoryTableTest, InOrderKeyframesEnterAtOnceWithTheirOdometryFactor) {
  TrajectoryTable table;
  std::vector<AdmittedKeyframe> out;
  ASSERT_TRUE(table.Offer(MakeKeyframe("R1", 900, 0), &out).ok());
  ASSERT_TRUE(table.Offer(MakeKeyframe("R2", 901, 0), &out).ok());
  ASSERT_TRUE(table.Offer(MakeKeyframe("R1", 900, 1), &out).ok());
  ASSERT_EQ(out.size(), 3u);
  EXPECT_TRUE(out[0].new_trajectory);
  EXPECT_EQ(out[0].key, (PoseKey{TrajectoryId(0), 0}));
  EXPECT_FALSE(out[0].previous);
  EXPECT_EQ(out[1].key, (PoseKey{TrajectoryId(1), 0}));
  EXPECT_EQ(out[2].key, (PoseKey{TrajectoryId(0), 1}));
  ASSERT_TRUE(out[2].previous);
  EXPECT_EQ(*out[2].previous, (PoseKey{TrajectoryId(0), 0}));
  EXPECT_DOUBLE_EQ(out[2].T_previous_this.x(), 0.5);
  EXPECT_DOUBLE_EQ(out[2].T_previous_this_covariance(0, 0), 1e-3);
  EXPECT_FALSE(out[2].bridged_gap);
  EXPECT_EQ(table.num_robots(), 2);
  EXPECT_EQ(table.num_keyframes(), 3);
  ASSERT_TRUE(table.Find({"R1", 900}));
  EXPECT_EQ(table.Find({"R1", 900})->num_keyframes(), 2);
  EXPECT_EQ(table.Find({"R2", 900}), nullptr);
}

TEST(TrajectoryTableTest, ReusedSequenceNumbersAreRefused) {
  TrajectoryTable table;
  std::vector<AdmittedKeyframe> out;
  ASSERT_TRUE(table.Offer(MakeKeyframe("R1", 1, 0), &out).ok());
  ASSERT_TRUE(table.Offer(MakeKeyframe("R1", 1, 1), &out).ok());
  EXPECT_EQ(table.Offer(MakeKeyframe("R1", 1, 1), &out).code(), ErrorCode::kDuplicateSequence);
  EXPECT_EQ(table.Offer(MakeKeyframe("R1", 1, 0), &out).code(), ErrorCode::kDuplicateSequence);
  ASSERT_TRUE(table.Offer(MakeKeyframe("R1", 1, 3), &out).ok());  // waits for 2
  EXPECT_EQ(table.Offer(MakeKeyframe("R1", 1, 3), &out).code(), ErrorCode::kDuplicateSequence);
  EXPECT_EQ(out.size(), 2u);
  EXPECT_EQ(table.num_held(), 1u);
  // The same seq in another session is a different keyframe.
  EXPECT_TRUE(table.Offer(MakeKeyframe("R1", 2, 0), &out).ok());
}

// The count of relayed encounters never decreases along a trajectory: a keyframe whose
// count is below an earlier keyframe's (admitted or waiting) or above a later waiting one's
// is refused, and the keyframe with that seq may still come with a sound count.
TEST(TrajectoryTableTest, ARelayCountThatGoesBackwardsIsRefused) {
  TrajectoryTable table;
  std::vector<AdmittedKeyframe> out;
  auto with_count = [](int32_t seq, int32_t relayed) {
    Keyframe k = MakeKeyframe("R1", 1, seq);
    k.encounters_relayed = relayed;
    return k;
  };
  ASSERT_TRUE(table.Offer(with_count(0, 0), &out).ok());
  ASSERT_TRUE(table.Offer(with_count(1, 2), &out).ok());
  EXPECT_EQ(table.Offer(with_count(2, 1), &out).code(), ErrorCode::kBadSequence);  // < admitted
  ASSERT_TRUE(table.Offer(with_count(4, 5), &out).ok());                           // waits for 2, 3
  EXPECT_EQ(table.Offer(with_count(3, 6), &out).code(), ErrorCode::kBadSequence);  // > later one
  EXPECT_EQ(table.Offer(with_count(5, 4), &out).code(), ErrorCode::kBadSequence);  // < earlier one
  EXPECT_EQ(table.Offer(with_count(2, 1), &out).code(), ErrorCode::kBadSequence);
  ASSERT_TRUE(table.Offer(with_count(3, 5), &out).ok());
  ASSERT_TRUE(table.Offer(with_count(2, 2), &out).ok());
  EXPECT_EQ(out.size(), 5u);
  EXPECT_EQ(table.num_held(), 0u);
  EXPECT_EQ(table.Offer(with_count(5, 4), &out).code(), ErrorCode::kBadSequence);
  ASSERT_TRUE(table.Offer(with_count(5, 5), &out).ok());
  // Another session counts from 0 again.
  Keyframe other = MakeKeyframe("R1", 2, 0);
  EXPECT_TRUE(table.Offer(other, &out).ok());
}

TEST(TrajectoryTableTest, ReorderedKeyframesWaitForTheMissingOne) {
  TrajectoryTable table;
  std::vector<AdmittedKeyframe> out;
  ASSERT_TRUE(table.Offer(MakeKeyframe("R1", 1, 0), &out).ok());
  ASSERT_TRUE(table.Offer(MakeKeyframe("R1", 1, 2), &out).ok());
  EXPECT_EQ(out.size(), 1u);
  ASSERT_TRUE(table.Offer(MakeKeyframe("R1", 1, 1), &out).ok());
  ASSERT_EQ(out.size(), 3u);
  EXPECT_EQ(out[1].key.index, 1);
  EXPECT_EQ(out[2].key.index, 2);
  EXPECT_FALSE(out[2].bridged_gap);
  EXPECT_EQ(table.Find({"R1", 1})->seqs, (std::vector<int32_t>{0, 1, 2}));
}

TEST(TrajectoryTableTest, LostKeyframeIsBridgedAfterTheHoldTime) {
  TrajectoryTableOptions options;
  options.max_hold_s = 1.2;
  options.gap_covariance_scale = 2.0;
  TrajectoryTable table(options);
  std::vector<AdmittedKeyframe> out;
  // The hold is measured on the caller's clock from the moment the gap opened.
  ASSERT_TRUE(table.Offer(MakeKeyframe("R1", 1, 0), 0, &out).ok());
  ASSERT_TRUE(table.Offer(MakeKeyframe("R1", 1, 2), 1'000'000, &out).ok());  // seq 1 is lost
  EXPECT_EQ(table.MissingRanges(TrajectoryId(0)),
            (std::vector<std::pair<int32_t, int32_t>>{{1, 1}}));
  ASSERT_TRUE(table.Offer(MakeKeyframe("R1", 1, 3), 2'000'000, &out).ok());  // 1.0 s open
  EXPECT_EQ(out.size(), 1u);
  table.Poll(2'200'001, &out);  // 1.2 s open: bridged
  ASSERT_EQ(out.size(), 3u);
  const AdmittedKeyframe& bridged = out[1];
  EXPECT_TRUE(bridged.bridged_gap);
  EXPECT_EQ(bridged.missing_steps, 1);
  EXPECT_EQ(bridged.key.index, 1);                     // solver indices stay dense
  EXPECT_DOUBLE_EQ(bridged.T_previous_this.x(), 1.0);  // from the odometry poses
  EXPECT_DOUBLE_EQ(bridged.T_previous_this_covariance(0, 0), 1e-3 * 2 * 2.0);
  EXPECT_FALSE(out[2].bridged_gap);
  EXPECT_EQ(table.num_bridged_gaps(), 1);
  EXPECT_TRUE(table.MissingRanges(TrajectoryId(0)).empty());
  EXPECT_EQ(table.NextSeq(TrajectoryId(0)), 4);
  // The lost keyframe arriving now is late, not a duplicate.
  EXPECT_EQ(table.Offer(MakeKeyframe("R1", 1, 1), 2'300'000, &out).code(),
            ErrorCode::kLateSequence);
  EXPECT_EQ(table.Offer(MakeKeyframe("R1", 1, 2), 2'300'000, &out).code(),
            ErrorCode::kDuplicateSequence);
}

TEST(TrajectoryTableTest, AKeyframeLateAfterALongPauseIsNotRefused) {
  // Issue 13: a keyframe 300 ms late after a 3 s pause of the robot was refused as a
  // duplicate, because the hold rule measured data time. On the server's clock it waits.
  TrajectoryTableOptions options;
  options.max_hold_s = 1.0;
  TrajectoryTable table(options);
  std::vector<AdmittedKeyframe> out;
  ASSERT_TRUE(table.Offer(MakeKeyframe("R1", 1, 0), 0, &out).ok());
  Keyframe after_pause = MakeKeyframe("R1", 1, 2);
  after_pause.utime = 4'000'000;
  Keyframe late = MakeKeyframe("R1", 1, 1);
  late.utime = 3'700'000;
  ASSERT_TRUE(table.Offer(after_pause, 10'000'000, &out).ok());
  ASSERT_TRUE(table.Offer(late, 10'300'000, &out).ok());
  ASSERT_EQ(out.size(), 3u);
  EXPECT_FALSE(out[1].bridged_gap);
  EXPECT_FALSE(out[2].bridged_gap);
  EXPECT_EQ(table.num_bridged_gaps(), 0);
}

TEST(TrajectoryTableTest, MissingRangesNameEveryGapBelowTheHighestWaitingSeq) {
  TrajectoryTable table;
  std::vector<AdmittedKeyframe> out;
  ASSERT_TRUE(table.Offer(MakeKeyframe("R1", 1, 0), &out).ok());
  ASSERT_TRUE(table.Offer(MakeKeyframe("R1", 1, 1), &out).ok());
  ASSERT_TRUE(table.Offer(MakeKeyframe("R1", 1, 4), &out).ok());
  ASSERT_TRUE(table.Offer(MakeKeyframe("R1", 1, 5), &out).ok());
  ASSERT_TRUE(table.Offer(MakeKeyframe("R1", 1, 8), &out).ok());
  EXPECT_EQ(table.MissingRanges(TrajectoryId(0)),
            (std::vector<std::pair<int32_t, int32_t>>{{2, 3}, {6, 7}}));
  EXPECT_EQ(table.NextSeq(TrajectoryId(0)), 2);
  // A trajectory first seen at seq 3 misses 0..2.
  ASSERT_TRUE(table.Offer(MakeKeyframe("R2", 2, 3), &out).ok());
  EXPECT_EQ(table.MissingRanges(TrajectoryId(1)),
            (std::vector<std::pair<int32_t, int32_t>>{{0, 2}}));
  EXPECT_EQ(table.NextSeq(TrajectoryId(1)), 0);
}

TEST(TrajectoryTableTest, LateStartBeginsAtTheLowestSeqAndFlushAdmitsTheRest) {
  TrajectoryTable table;
  std::vector<AdmittedKeyframe> out;
  ASSERT_TRUE(table.Offer(MakeKeyframe("R3", 5, 7), &out).ok());
  ASSERT_TRUE(table.Offer(MakeKeyframe("R3", 5, 8), &out).ok());
  EXPECT_TRUE(out.empty());  // seq 0..6 might still come
  table.FlushHeld(&out);
  ASSERT_EQ(out.size(), 2u);
  EXPECT_TRUE(out[0].new_trajectory);
  EXPECT_FALSE(out[0].previous);
  EXPECT_DOUBLE_EQ(out[0].T_local_pose.x(), 3.5);
  EXPECT_FALSE(out[1].bridged_gap);
}

TEST(TrajectoryTableTest, FindsTheSessionOfARobotAtATimeAndInterpolates) {
  TrajectoryTable table;
  std::vector<AdmittedKeyframe> out;
  for (int s = 0; s < 4; ++s) ASSERT_TRUE(table.Offer(MakeKeyframe("R1", 10, s), &out).ok());
  for (int s = 0; s < 4; ++s) {
    ASSERT_TRUE(table.Offer(MakeKeyframe("R1", 20, s, 10'000'000), &out).ok());  // a restart
  }
  EXPECT_EQ(table.TrajectoryOfRobotAt("R1", 1'000'000)->agent_trajectory_id, 10);
  EXPECT_EQ(table.TrajectoryOfRobotAt("R1", 11'000'000)->agent_trajectory_id, 20);
  EXPECT_EQ(table.TrajectoryOfRobotAt("R1", -5)->agent_trajectory_id, 10);
  EXPECT_EQ(table.TrajectoryOfRobotAt("R9", 0), nullptr);

  const TrajectoryRecord& r = *table.Find({"R1", 10});  // keyframes at 0, 0.5, 1.0, 1.5 s
  EXPECT_EQ(r.NearestIndex(700'000), 1);
  EXPECT_EQ(r.NearestIndex(800'000), 2);
  EXPECT_EQ(r.NearestIndex(-1), 0);
  EXPECT_EQ(r.NearestIndex(9'000'000), 3);
  EXPECT_DOUBLE_EQ(r.OdometryPoseAt(600'000).x(), 0.6);
  EXPECT_DOUBLE_EQ(r.OdometryPoseAt(9'000'000).x(), 1.5);
}

}  // namespace
}  // namespace anchormap

namespace anchormap {
namespace {

TEST(TrajectoryTableTest, AReusedIdAfterARestartStartsANewTrajectory) {
  // Issue 13: a restarted agent given its old --trajectory-id had every keyframe refused
  // as a duplicate. Its seq 0 (another time) starts a new trajectory instead.
  TrajectoryTable table;
  std::vector<AdmittedKeyframe> out;
  for (int s = 0; s < 4; ++s) ASSERT_TRUE(table.Offer(MakeKeyframe("R1", 7, s), &out).ok());
  EXPECT_EQ(table.Offer(MakeKeyframe("R1", 7, 0), &out).code(), ErrorCode::kDuplicateSequence);
  for (int s = 0; s < 3; ++s) {
    ASSERT_TRUE(table.Offer(MakeKeyframe("R1", 7, s, 60'000'000), &out).ok()) << s;
  }
  EXPECT_EQ(table.num_reused_ids(), 1);
  ASSERT_EQ(table.records().size(), 2u);
  EXPECT_EQ(table.records()[0].num_keyframes(), 4);  // the old session keeps its keyframes
  EXPECT_EQ(table.records()[1].num_keyframes(), 3);
  EXPECT_EQ(table.Find({"R1", 7}), &table.records()[1]);
  EXPECT_TRUE(out[4].new_trajectory);
  EXPECT_EQ(out[4].key, (PoseKey{TrajectoryId(1), 0}));
  // Its duplicates are recognised as such.
  EXPECT_EQ(table.Offer(MakeKeyframe("R1", 7, 2, 60'000'000), &out).code(),
            ErrorCode::kDuplicateSequence);
}

}  // namespace
}  // namespace anchormap
