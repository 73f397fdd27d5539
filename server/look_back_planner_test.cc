// The look back on group change (LookBackPlanner), through ScanEncounters.
#include "server/look_back_planner.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <memory>
#include <random>
#include <set>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "common/geometry/angle.h"
#include "server/join_free_space.h"
#include "server/keyframe_overlap.h"
#include "server/mapping_server.h"
#include "server/relative_pose.h"
#include "server/scan_encounters.h"
#include "tests/scan_encounter_testing/scan_encounter_scenarios.h"
#include "tests/scan_testing/scan_scenarios.h"
#include "tests/testing/straight_keyframes.h"

namespace anchormap {
namespace {

using testing::DriveKeyframes;
using testing::OdometryNoise;
using testing::SyntheticWorld;

// The look back when groups change: R1, R2 and R3 lap LoopWorld from three corners, none joined.
// R3 holds one true, map-verified candidate against R2 (R2[10]-R3[35]), alone: nothing joins.
// When a direct encounter then joins R1 and R2, the hypothesis places R3's past keyframes in
// their frame, and those it puts near R1's submaps are searched there (R3 passed R1's south and
// east sides before R1 and R2 joined); a match found so confirms R2[10]-R3[35] across the pairs.
class LookBackTest : public ::testing::Test, protected testing::ThreeLaps {
 protected:
  void SetUp() override { ASSERT_TRUE(Drive(/*r1_sees_r2=*/false)); }

  // R1 reports seeing R2 where both start: R1 and R2 join.
  void JoinR1AndR2() {
    ASSERT_TRUE(server_->OnEncounter(SeenByR1AtTheStart(1)).ok());
    server_->Flush();
    ASSERT_TRUE(InOneFrame(server_->smoother(), TrajectoryId(0), TrajectoryId(1)));
  }

  // R3[35] seen from R2[10], as the world has it.
  EncounterCandidate Hypothesis() const {
    EncounterCandidate c;
    c.a = {TrajectoryId(1), 10};
    c.b = {TrajectoryId(2), 35};
    c.T_a_b = Compose(paths_[1][10].Inverse(), paths_[2][35]);
    c.covariance = Eigen::Vector3d(4e-4, 4e-4, 2.5e-5).asDiagonal();
    c.utime = 1'000'000 + 500'000 * int64_t{35};
    return c;
  }

  // The world's distance from R3[j] to R1[i].
  double R3ToR1(int32_t j, int32_t i) const {
    return (paths_[2][static_cast<size_t>(j)].translation() -
            paths_[0][static_cast<size_t>(i)].translation())
        .norm();
  }

  struct Looked {
    std::vector<ScanEncounterState::Match> searches;  // submitted at the group change
    int64_t look_backs = 0;
    std::vector<EncounterConstraint> emitted;  // once the searches' results are used
  };
  // With the hypothesis kept or not: the searches the group change submits (held back by the
  // schedule's lag, then used).
  Looked LookBack(bool hypothesis,
                  int look_back_max_per_change = ScanEncounterOptions{}.look_back_max_per_change) {
    ScanEncounterOptions options;
    options.look_back_max_per_change = look_back_max_per_change;
    options.first_join_hold_s = 0.0;
    options.near_catch_up_every = 0;  // no near search between R1 and R2 (a test of its own)
    MatchPool pool(1);
    ScanEncounters source(options, &pool, MatchSchedule{100.0});
    EncounterSourceOutput out;
    const auto poll = [&](int64_t utime) {
      const GraphView graph{server_->table(), server_->smoother(), &server_->mutable_smoother()};
      source.Poll(utime, graph, &out);
    };
    poll(100'000'000);
    if (hypothesis) {
      const GraphView graph{server_->table(), server_->smoother(), &server_->mutable_smoother()};
      source.OfferCandidate(Hypothesis(), graph, &out);
    }
    poll(100'000'000);
    EXPECT_TRUE(out.constraints.empty());
    JoinR1AndR2();
    poll(100'000'000);
    Looked looked;
    looked.searches = source.ExportState().matches;
    looked.look_backs = source.look_backs();
    poll(300'000'000);  // the searches' results are due
    looked.emitted = out.constraints;
    return looked;
  }
};

TEST_F(LookBackTest, AGroupChangeLooksBackWhereTheHypothesisPutsThePastKeyframes) {
  const ScanEncounterOptions defaults;
  // R1's submap centres: keyframes 5, 15, ... whose submap R1 has driven (half width 5).
  std::vector<int32_t> centres;
  for (int32_t c = 5; c + 5 < static_cast<int32_t>(paths_[0].size()); c += 10) {
    centres.push_back(c);
  }
  const auto nearest_centre_m = [&](int32_t j) {
    double nearest = 1e9;
    for (const int32_t c : centres) nearest = std::min(nearest, R3ToR1(j, c));
    return nearest;
  };
  // R3's keyframes within the near search's reach of one of R1's submaps: more than the cap,
  // all before R3[35] (R3 then drives on along the north side, away from R1's path).
  int within_reach = 0;
  for (int32_t j = 0; j < static_cast<int32_t>(paths_[2].size()); ++j) {
    if (nearest_centre_m(j) <= defaults.near_distance_m) {
      ++within_reach;
      EXPECT_LT(j, 35);
    }
  }
  ASSERT_GT(within_reach, defaults.look_back_max_per_change);

  const Looked looked = LookBack(/*hypothesis=*/true);
  ASSERT_EQ(looked.look_backs, defaults.look_back_max_per_change);
  ASSERT_EQ(looked.searches.size(), static_cast<size_t>(defaults.look_back_max_per_change));
  double farthest_m = 0.0;
  for (const ScanEncounterState::Match& m : looked.searches) {
    // R3's past keyframes against R1's submaps, global searches of the submap the hypothesis
    // puts them nearest: the nearest first, so within 2 m of its centre in the world.
    EXPECT_TRUE(m.global);
    EXPECT_EQ(m.key.trajectory, TrajectoryId(2));
    EXPECT_EQ(m.center.trajectory, TrajectoryId(0));
    EXPECT_LT(R3ToR1(m.key.index, m.center.index), nearest_centre_m(m.key.index) + 0.5);
    farthest_m = std::max(farthest_m, R3ToR1(m.key.index, m.center.index));
  }
  std::printf(
      "looked back at %zu of R3's %d keyframes within %.1f m of R1's submaps, the "
      "farthest %.2f m from its centre\n",
      looked.searches.size(), within_reach, defaults.near_distance_m, farthest_m);
  EXPECT_LT(farthest_m, 2.0);
  // The matches confirm the hypothesis across the pairs: R3 joins R1 and R2, every constraint
  // within 5 cm and 0.01 rad of the world.
  int r1_r3 = 0;
  bool hypothesis_in = false;
  for (const EncounterConstraint& c : looked.emitted) {
    const Pose2 truth = Compose(
        paths_[static_cast<size_t>(c.a.trajectory.value())][static_cast<size_t>(c.a.index)]
            .Inverse(),
        paths_[static_cast<size_t>(c.b.trajectory.value())][static_cast<size_t>(c.b.index)]);
    EXPECT_LT((c.measured_T_a_b.translation() - truth.translation()).norm(), 0.05);
    EXPECT_LT(std::abs(WrapAngle(c.measured_T_a_b.theta() - truth.theta())), 0.01);
    if (c.a.trajectory == TrajectoryId(0) && c.b.trajectory == TrajectoryId(2)) ++r1_r3;
    if (c.a == Hypothesis().a && c.b == Hypothesis().b) hypothesis_in = true;
  }
  EXPECT_GE(r1_r3, 1);
  EXPECT_TRUE(hypothesis_in);
  // Not looking back, the hypothesis stays alone.
  EXPECT_TRUE(LookBack(/*hypothesis=*/true, /*look_back_max_per_change=*/0).emitted.empty());
}

TEST_F(LookBackTest, WithoutAHypothesisTheGroupChangeLooksAtNothing) {
  const Looked looked = LookBack(/*hypothesis=*/false);
  EXPECT_EQ(looked.look_backs, 0);
  EXPECT_TRUE(looked.searches.empty());
  EXPECT_TRUE(looked.emitted.empty());
}

}  // namespace
}  // namespace anchormap
