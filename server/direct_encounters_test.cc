#include "server/direct_encounters.h"

#include <gtest/gtest.h>

#include "common/solver/smoother.h"

namespace anchormap {
namespace {

// Two robots in a world frame; each keyframe's odometry pose is its true pose in the
// robot's own local frame (odometry started at T_world_local).
struct World {
  Pose2 T_world_local_a{0.0, 0.0, 0.0};
  Pose2 T_world_local_b{5.0, 2.0, 1.0};
  // Robot a drives along its x at 1 m/s, robot b turns on a circle; both at time t (s).
  static Pose2 LocalA(double t) { return Pose2(1.0 * t, 0.0, 0.0); }
  static Pose2 LocalB(double t) { return Pose2(0.5 * t, 0.2 * t, 0.3 * t); }
};

Keyframe MakeKeyframe(const std::string& robot, int64_t trajectory, int32_t seq, int64_t utime,
                      const Pose2& pose) {
  Keyframe k;
  k.robot = robot;
  k.trajectory_id = trajectory;
  k.seq = seq;
  k.utime = utime;
  k.T_local_pose = pose;
  return k;
}

class DirectEncountersTest : public ::testing::Test {
 protected:
  void AddKeyframes(const std::string& robot, int64_t trajectory, const std::vector<double>& times,
                    Pose2 (*pose_at)(double)) {
    std::vector<AdmittedKeyframe> admitted;
    for (size_t i = 0; i < times.size(); ++i) {
      const int64_t seq = next_seq_[robot]++;
      ASSERT_TRUE(table_
                      .Offer(MakeKeyframe(robot, trajectory, static_cast<int32_t>(seq),
                                          static_cast<int64_t>(times[i] * 1e6), pose_at(times[i])),
                             &admitted)
                      .ok());
    }
  }
  Encounter MakeEncounter(double t) const {
    Encounter e;
    e.utime = static_cast<int64_t>(t * 1e6);
    e.observer = "A";
    e.observed = "B";
    e.T_observer_observed = Between(Compose(world_.T_world_local_a, World::LocalA(t)),
                                    Compose(world_.T_world_local_b, World::LocalB(t)));
    e.covariance = Eigen::Vector3d(0.01, 0.01, 0.001).asDiagonal();
    return e;
  }
  GraphView View() const { return GraphView{table_, smoother_}; }

  World world_;
  TrajectoryTable table_;
  Smoother smoother_;
  std::map<std::string, int64_t> next_seq_;
};

TEST_F(DirectEncountersTest, TieCorrectsForTheMotionBetweenEncounterAndKeyframes) {
  // Keyframes of A at 0, 1.0, 1.1 s and of B at 0, 0.95, 1.3 s; the encounter at 1.04 s.
  // Nearest: A's at 1.0 s, B's at 0.95 s. Both motions are linear in time between
  // keyframes for A; B's is curved, so the interpolation is only approximate.
  AddKeyframes("A", 1, {0.0, 1.0, 1.1}, World::LocalA);
  AddKeyframes("B", 2, {0.0, 0.95, 1.3}, World::LocalB);
  const Encounter e = MakeEncounter(1.04);
  const Result<EncounterConstraint> tie =
      TieEncounter(e, *table_.Find({"A", 1}), *table_.Find({"B", 2}), DirectEncounterOptions{});
  ASSERT_TRUE(tie.ok()) << tie.status().message();
  EXPECT_EQ(tie->a, (PoseKey{TrajectoryId(0), 1}));
  EXPECT_EQ(tie->b, (PoseKey{TrajectoryId(1), 1}));
  // The truth: keyframe B(0.95) seen from keyframe A(1.0).
  const Pose2 truth = Between(Compose(world_.T_world_local_a, World::LocalA(1.0)),
                              Compose(world_.T_world_local_b, World::LocalB(0.95)));
  const Eigen::Vector3d error = PoseError(tie->measured_T_a_b, truth);
  // Interpolating B's curved motion over 0.35 s leaves a few mm.
  EXPECT_LT(error.head<2>().norm(), 5e-3) << error.transpose();
  EXPECT_LT(std::abs(error.z()), 1e-9);  // headings interpolate exactly (linear in time)
  // Without the correction the error would be the 4 cm A drove plus B's motion.
  EXPECT_GT(PoseError(e.T_observer_observed, truth).head<2>().norm(), 0.04);
  // Covariance: the measurement's plus the corrections' inflation, still SPD.
  EXPECT_GT(tie->covariance(0, 0) + tie->covariance(1, 1), 0.02);
  EXPECT_GT(tie->covariance(2, 2), 0.001);
  EXPECT_LT(tie->covariance.trace(), 0.03);
  EXPECT_TRUE(tie->covariance.isApprox(tie->covariance.transpose()));
}

TEST_F(DirectEncountersTest, ExactWhenKeyframesAreAtTheEncounterTime) {
  AddKeyframes("A", 1, {0.0, 2.0}, World::LocalA);
  AddKeyframes("B", 2, {0.0, 2.0}, World::LocalB);
  const Encounter e = MakeEncounter(2.0);
  const Result<EncounterConstraint> tie =
      TieEncounter(e, *table_.Find({"A", 1}), *table_.Find({"B", 2}), DirectEncounterOptions{});
  ASSERT_TRUE(tie.ok());
  EXPECT_LT(PoseError(tie->measured_T_a_b, e.T_observer_observed).norm(), 1e-12);
}

TEST_F(DirectEncountersTest, WaitsUntilBothRobotsHaveAKeyframeAfterTheEncounter) {
  DirectEncounters source;
  EncounterSourceOutput out;
  AddKeyframes("A", 1, {0.0, 1.0, 2.0}, World::LocalA);
  AddKeyframes("B", 2, {0.0, 1.0}, World::LocalB);
  source.OnEncounterMessage(MakeEncounter(1.6), View(), &out);
  EXPECT_TRUE(out.constraints.empty());
  EXPECT_EQ(source.pending(), 1u);
  AddKeyframes("B", 2, {1.6}, World::LocalB);
  source.OnKeyframeAdded(PoseKey{TrajectoryId(1), 2}, View(), &out);
  ASSERT_EQ(out.constraints.size(), 1u);
  EXPECT_EQ(out.constraints[0].a, (PoseKey{TrajectoryId(0), 2}));  // A's nearest to 1.6 s: 2.0 s
  EXPECT_EQ(out.constraints[0].b, (PoseKey{TrajectoryId(1), 2}));
  EXPECT_EQ(source.pending(), 0u);
  EXPECT_TRUE(out.rejections.empty());
}

TEST_F(DirectEncountersTest, UnknownRobotIsRefusedAfterTheWaitAndFarKeyframesAreRefused) {
  DirectEncounterOptions options;
  options.max_wait_s = 5.0;
  options.max_time_offset_s = 0.5;
  DirectEncounters source(options);
  EncounterSourceOutput out;
  AddKeyframes("A", 1, {0.0, 1.0}, World::LocalA);
  Encounter ghost = MakeEncounter(1.0);
  ghost.observed = "GHOST";
  source.OnEncounterMessage(ghost, View(), &out);
  source.Poll(5'500'000, View(), &out);  // 4.5 s later: still waiting
  EXPECT_TRUE(out.rejections.empty());
  source.Poll(6'100'000, View(), &out);
  ASSERT_EQ(out.rejections.size(), 1u);
  EXPECT_EQ(out.rejections[0].code(), ErrorCode::kUnknownRobot);

  AddKeyframes("B", 2, {0.0, 3.0}, World::LocalB);  // nothing within 0.5 s of 0.8 s
  source.OnEncounterMessage(MakeEncounter(0.8), View(), &out);
  ASSERT_EQ(out.rejections.size(), 2u);
  EXPECT_EQ(out.rejections[1].code(), ErrorCode::kNoKeyframeNearTime);
  EXPECT_TRUE(out.constraints.empty());
}

TEST_F(DirectEncountersTest, FlushTiesWhatItCanAndBoundsThePendingList) {
  DirectEncounterOptions options;
  options.max_pending = 2;
  DirectEncounters source(options);
  EncounterSourceOutput out;
  AddKeyframes("A", 1, {0.0, 1.0}, World::LocalA);
  AddKeyframes("B", 2, {0.0, 0.9}, World::LocalB);
  for (double t : {0.95, 0.96, 0.97}) source.OnEncounterMessage(MakeEncounter(t), View(), &out);
  ASSERT_EQ(out.rejections.size(), 1u);  // the first one pushed out
  EXPECT_EQ(out.rejections[0].code(), ErrorCode::kQueueFull);
  EXPECT_EQ(source.pending(), 2u);  // B has no keyframe after 0.9 s yet
  source.Flush(View(), &out);
  EXPECT_EQ(out.constraints.size(), 2u);
  EXPECT_EQ(source.pending(), 0u);
}

}  // namespace
}  // namespace anchormap
