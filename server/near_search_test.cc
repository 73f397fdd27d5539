// The near search between joined trajectories (NearSearch): its window, drift terms, the
// acceptance of hand-made matches and the catch-up of newly joined pairs, through ScanEncounters.
#include "server/near_search.h"

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
using testing::ParallelTracksCandidate;
using testing::SyntheticWorld;

// The wide near search's acceptance on hand-made matches between the parallel tracks, joined
// by R1 seeing R2 at their start: R2[j] seen from R1[i] is known to about 0.1 m at keyframe 20.
class WideNearTest : public ::testing::Test {
 protected:
  void SetUp() override {
    server_ = testing::DriveParallelTracks(/*seen_at_start=*/true);
    ASSERT_NE(server_, nullptr);
  }

  // R2[j] (the query) matched in R1[i]'s submap, `shift` off the truth across the tracks.
  static EncounterCandidate Match(int32_t i, int32_t j, double shift_m = 0.0) {
    return ParallelTracksCandidate(i, j, 0.0, shift_m,
                                   Eigen::Vector3d(4e-4, 4e-4, 2.5e-5).asDiagonal());
  }

  // What the source emits for the offers, as wide near matches or through the plain gate.
  std::vector<EncounterConstraint> Offer(const std::vector<EncounterCandidate>& matches,
                                         bool wide = true) {
    ScanEncounters source;
    const GraphView graph{server_->table(), server_->smoother(), &server_->mutable_smoother()};
    EncounterSourceOutput out;
    for (const EncounterCandidate& c : matches) {
      if (wide) {
        source.OfferNearMatch(c, /*wide=*/true, graph, &out);
      } else {
        source.OfferCandidate(c, graph, &out);
      }
    }
    source.Flush(graph, &out);
    stats_ = source.stats();
    return out.constraints;
  }

  std::unique_ptr<MappingServer> server_;
  CandidateStats stats_;
};

TEST_F(WideNearTest, ALoneMatchEntersNothing) {
  EXPECT_TRUE(Offer({Match(20, 20)}).empty());
  EXPECT_EQ(stats_.unconfirmed, 1);  // held to the end of input, then given up
  EXPECT_EQ(stats_.kept, 0);
  EXPECT_EQ(stats_.accepted, 0);
}

TEST_F(WideNearTest, TwoMatchesThatAgreeEnterTogether) {
  const std::vector<EncounterConstraint> entered = Offer({Match(20, 20), Match(20, 23)});
  ASSERT_EQ(entered.size(), 2u);
  EXPECT_EQ(entered[0].b.index, 20);
  EXPECT_EQ(entered[1].b.index, 23);
  EXPECT_EQ(entered[0].kind, ConstraintKind::kScanEncounter);
  EXPECT_EQ(stats_.accepted, 2);
  EXPECT_EQ(stats_.kept, 0);
}

TEST_F(WideNearTest, TheNextKeyframeIsNoSecondOpinion) {
  EXPECT_TRUE(Offer({Match(20, 20), Match(20, 21)}).empty());
  EXPECT_EQ(stats_.unconfirmed, 2);
}

TEST_F(WideNearTest, AMatchThatDisagreesConfirmsNothing) {
  // 0.3 m across the tracks: within the widened gate, but not the same transform as the
  // first match through three keyframes of odometry (a few centimetres).
  EXPECT_TRUE(Offer({Match(20, 20), Match(20, 23, 0.3)}).empty());
  EXPECT_EQ(stats_.unconfirmed, 2);
  EXPECT_EQ(stats_.gate_rejected, 0);
}

TEST_F(WideNearTest, AMatchFarOffTheEstimateIsRefused) {
  EXPECT_TRUE(Offer({Match(20, 20, 2.0), Match(20, 23, 2.0)}).empty());
  EXPECT_EQ(stats_.gate_rejected, 2);
  EXPECT_EQ(stats_.kept, 0);
}

TEST_F(WideNearTest, TwoMatchesThatAgreeOffTheEstimateEnterWhereThePlainGateRefuses) {
  // Both 0.45 m across (the estimate drifted): the plain gate refuses each, the widened one
  // holds the first and the second confirms it.
  EXPECT_TRUE(Offer({Match(20, 20, 0.45), Match(20, 23, 0.45)}, /*wide=*/false).empty());
  EXPECT_EQ(stats_.gate_rejected, 2);
  EXPECT_EQ(Offer({Match(20, 20, 0.45), Match(20, 23, 0.45)}).size(), 2u);
  EXPECT_EQ(stats_.accepted, 2);
}

// The near search's drift term on hand-made matches between the parallel tracks, joined by R1
// seeing R2 at their first keyframes: at keyframe 20 the robots drove 40 m since that tie, so
// the drift term is 0.4 m and 0.04 rad (the defaults' 0.01 m and 0.001 rad per metre), while
// the estimate's own heading is known to about 0.0065 rad (odometry 0.001 rad a step).
class NearDriftTest : public ::testing::Test {
 protected:
  void SetUp() override {
    server_ = testing::DriveParallelTracks(/*seen_at_start=*/true);
    ASSERT_NE(server_, nullptr);
  }

  // R2[j] matched in R1[i]'s submap where R2's track is really turned by `turn_rad` about its
  // first keyframe (the tie): off the estimate by the turn and by 0.04 m across per metre per
  // 0.04 rad, as a heading error the tie does not see grows with the distance from it.
  static EncounterCandidate Match(int32_t i, int32_t j, double turn_rad) {
    EncounterCandidate c =
        ParallelTracksCandidate(i, j, 0.0, 0.0, Eigen::Vector3d(4e-4, 4e-4, 2.5e-5).asDiagonal());
    c.T_a_b = Pose2(j * std::cos(turn_rad) - i, 3.0 + j * std::sin(turn_rad), turn_rad);
    return c;
  }

  // What the source emits for near matches of a window that was not wide; `ties`: the graph
  // view carries the server's ties (else the drift term is zero, the rule before).
  std::vector<EncounterConstraint> Offer(const std::vector<EncounterCandidate>& matches,
                                         bool ties = true) {
    ScanEncounters source;
    const GraphView graph{server_->table(), server_->smoother(), &server_->mutable_smoother(),
                          ties ? &server_->ties() : nullptr};
    EncounterSourceOutput out;
    for (const EncounterCandidate& c : matches)
      source.OfferNearMatch(c, /*wide=*/false, graph, &out);
    held_before_flush_ = source.stats().kept;
    source.Flush(graph, &out);
    stats_ = source.stats();
    return out.constraints;
  }

  std::unique_ptr<MappingServer> server_;
  CandidateStats stats_;
  int64_t held_before_flush_ = 0;
};

TEST_F(NearDriftTest, TheTieIsTheDirectEncounter) {
  ASSERT_EQ(server_->ties().size(), 1);
  ScanEncounters source;
  const GraphView graph{server_->table(), server_->smoother(), &server_->mutable_smoother(),
                        &server_->ties()};
  const Eigen::Matrix3d drift =
      source.NearDrift({TrajectoryId(0), 20}, {TrajectoryId(1), 20}, graph);
  EXPECT_NEAR(std::sqrt(drift(0, 0)), 0.4, 1e-9);
  EXPECT_NEAR(std::sqrt(drift(2, 2)), 0.04, 1e-9);
  // Without the server's ties, none.
  EXPECT_TRUE(
      source
          .NearDrift({TrajectoryId(0), 20}, {TrajectoryId(1), 20},
                     GraphView{server_->table(), server_->smoother(), &server_->mutable_smoother()})
          .isZero());
}

TEST_F(NearDriftTest, AMatchOnTheEstimateEntersAtOnce) {
  EXPECT_EQ(Offer({Match(20, 20, 0.0)}).size(), 1u);
  EXPECT_EQ(stats_.accepted, 1);
  EXPECT_EQ(held_before_flush_, 0);
}

TEST_F(NearDriftTest, TwoMatchesTurnedOffTheEstimateEnterTogether) {
  // 0.05 rad and 1 m across at keyframe 20: the plain gate refuses both on the heading alone
  // (about 6 sigma)...
  const std::vector<EncounterCandidate> turned{Match(20, 20, 0.05), Match(20, 23, 0.05)};
  EXPECT_TRUE(Offer(turned, /*ties=*/false).empty());
  EXPECT_EQ(stats_.gate_rejected, 2);
  // ... the gate with the drift of 40 m holds the first, and the second, three keyframes on,
  // agrees with it through the estimate: both enter.
  const std::vector<EncounterConstraint> entered = Offer(turned);
  ASSERT_EQ(entered.size(), 2u);
  EXPECT_EQ(entered[0].b.index, 20);
  EXPECT_EQ(entered[1].b.index, 23);
  EXPECT_EQ(stats_.accepted, 2);
  EXPECT_EQ(stats_.gate_rejected, 0);
}

TEST_F(NearDriftTest, ALoneMatchTurnedOffTheEstimateIsHeldNotAccepted) {
  EXPECT_TRUE(Offer({Match(20, 20, 0.05)}).empty());
  EXPECT_EQ(held_before_flush_, 1);
  EXPECT_EQ(stats_.unconfirmed, 1);  // given up at the end of input
  EXPECT_EQ(stats_.accepted, 0);
}

TEST_F(NearDriftTest, TwoMatchesThatDisagreeEnterNothing) {
  // Each within the drifted gate, but turned differently: not one transform.
  EXPECT_TRUE(Offer({Match(20, 20, 0.05), Match(20, 23, -0.05)}).empty());
  EXPECT_EQ(stats_.unconfirmed, 2);
  EXPECT_EQ(stats_.accepted, 0);
}

TEST_F(NearDriftTest, AMatchBeyondTheDriftIsRefused) {
  // 0.2 rad and 4 m across: 5 sigma of the drift term in heading, 10 across.
  EXPECT_TRUE(Offer({Match(20, 20, 0.2), Match(20, 23, 0.2)}).empty());
  EXPECT_EQ(stats_.gate_rejected, 2);
  EXPECT_EQ(stats_.kept, 0);
}

// ACES 3 robots simultaneous, R1 at 474-487 s against R3's 1071 s pass: the estimate's 1-sigma
// was 0.33 m and 0.0177 rad, the true match 1.62 m and 0.093 rad off it, about 135 m of both
// robots' drive from the nearest tie. Without the drift term the window (1 m) did not hold it
// and the plain gate refused its heading (chi-square 28 against 11.34).
TEST(NearSearchWindowTest, TheDriftTermReachesWhereTheEstimateDrifted) {
  const ScanEncounterOptions options;
  const Eigen::Matrix3d estimate =
      Eigen::Vector3d(0.33 * 0.33, 0.33 * 0.33, 0.0177 * 0.0177).asDiagonal();
  const Eigen::Vector3d offset(-0.53, -1.53, 0.093);
  bool wide = true;
  const LocalMatchOptions before = NearSearchWindow(estimate, options, &wide);
  EXPECT_FALSE(wide);
  // Its search finds every lattice score UseMatches keeps (>= near_min_score), no lower one.
  EXPECT_LT(before.match.min_score, options.near_min_score);
  EXPECT_EQ(std::nextafter(before.match.min_score, 1.0), options.near_min_score);
  EXPECT_LT(before.linear_window_m, std::abs(offset.y()));
  const double drive_m = 135.0;
  const double m = options.near_drift_per_m * drive_m, rad = options.near_drift_rad_per_m * drive_m;
  const Eigen::Matrix3d drifted =
      estimate + Eigen::Matrix3d(Eigen::Vector3d(m * m, m * m, rad * rad).asDiagonal());
  const LocalMatchOptions after = NearSearchWindow(drifted, options, &wide);
  EXPECT_TRUE(wide);  // 3 x 1.39 m: searched by branch and bound, held for the pair rule
  EXPECT_GT(after.linear_window_m, std::abs(offset.y()));
  EXPECT_LE(after.linear_window_m, options.near_wide_max_window_m);
  EXPECT_GT(after.angular_window_rad, offset.z());
  EXPECT_GE(after.match.min_score, options.near_min_score);
  // And the gate: the plain one refuses the match, the drifted one accepts it.
  const Eigen::Matrix3d match = Eigen::Vector3d(4e-4, 4e-4, 2.5e-5).asDiagonal();
  const Pose2 measured(offset.x(), offset.y(), offset.z());
  EXPECT_GT(Mahalanobis2(Pose2(), measured, estimate + match), options.gate_chi2);
  EXPECT_LT(Mahalanobis2(Pose2(), measured, drifted + match), options.gate_chi2);
}

// Beyond NearWindowSaturatingDrive the drift term widens nothing more: the window of any longer
// drive is the same to the bit, whatever the prediction's covariance (so the tie graph need
// not be searched further).
TEST(NearSearchWindowTest, BeyondTheSaturatingDriveTheWindowIsTheSame) {
  const ScanEncounterOptions options;
  const double saturated = NearWindowSaturatingDrive(options);
  EXPECT_NEAR(saturated, 200.0, 1e-3);  // 6 m / (3 x 0.01) and 0.6 rad / (3 x 0.001)
  for (const double sigma : {0.0, 0.05, 0.5, 3.0}) {
    const Eigen::Matrix3d estimate =
        Eigen::Vector3d(sigma * sigma, 0.25 * sigma * sigma, 0.01 * sigma * sigma).asDiagonal();
    bool wide_at = false;
    const LocalMatchOptions at =
        NearSearchWindow(estimate + NearDriftOf(saturated, options), options, &wide_at);
    for (const double drive : {saturated * 1.0001, 2.0 * saturated, 1e4}) {
      bool wide = false;
      const LocalMatchOptions beyond =
          NearSearchWindow(estimate + NearDriftOf(drive, options), options, &wide);
      EXPECT_EQ(wide, wide_at);
      EXPECT_EQ(beyond.linear_window_m, at.linear_window_m);
      EXPECT_EQ(beyond.angular_window_rad, at.angular_window_rad);
      EXPECT_EQ(beyond.match.min_score, at.match.min_score);
    }
    EXPECT_EQ(at.linear_window_m, options.near_wide_max_window_m);
    EXPECT_EQ(at.angular_window_rad, options.max_window_rad);
  }
  // A little short of it, the window is still growing.
  bool wide = false;
  EXPECT_LT(NearSearchWindow(NearDriftOf(0.9 * saturated, options), options, &wide).linear_window_m,
            options.near_wide_max_window_m);
}

// The pairs in one frame are caught up once: R1-R2 at the first poll, then none while the frames
// stay the same, and R1-R3 and R2-R3 once an encounter brings R3 into their frame.
// R1 and R2 joined by a direct encounter at their first keyframes, R3 not (testing::ThreeLaps).
class CatchUpTest : public ::testing::Test, protected testing::ThreeLaps {
 protected:
  void SetUp() override { ASSERT_TRUE(Drive(/*r1_sees_r2=*/true)); }
};

TEST_F(CatchUpTest, APairIsCaughtUpWhenItComesIntoOneFrame) {
  using Pair = ScanEncounterState::Pair;
  const TrajectoryId r1(0), r2(1), r3(2);
  ScanEncounterOptions options;
  options.near_catch_up_every = 10;  // a few searches per pair: the test is of the pairs
  ScanEncounters source(options);
  EncounterSourceOutput out;
  const auto poll = [&] {
    const GraphView graph{server_->table(), server_->smoother(), &server_->mutable_smoother()};
    source.Poll(100'000'000, graph, &out);
    return source.ExportState().near_joined;
  };
  EXPECT_EQ(poll(), (std::set<Pair>{{r1, r2}}));
  EXPECT_EQ(poll(), (std::set<Pair>{{r1, r2}}));
  ASSERT_TRUE(server_->OnEncounter(SeenByR1AtTheStart(2)).ok());
  server_->Flush();
  ASSERT_TRUE(InOneFrame(server_->smoother(), r1, r3));
  EXPECT_EQ(poll(), (std::set<Pair>{{r1, r2}, {r1, r3}, {r2, r3}}));
}

}  // namespace
}  // namespace anchormap
