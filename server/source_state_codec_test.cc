// The scan-matching sources' state codec: a kept wide hypothesis's weak flag is written
// (a restored server must pair it as the uninterrupted one would), and a version-2
// snapshot's state, written before the flag existed, is read with none weak; the scan
// encounters' wide near matches (in flight and held) likewise from version 5.

#include "server/source_state_codec.h"

#include <cstddef>
#include <cstdint>
#include <vector>

#include <gtest/gtest.h>

#include "server/snapshot_codec.h"

namespace anchormap {
namespace {

LoopClosureState StateWithOneKeptHypothesis(bool weak) {
  LoopClosureState state;
  state.now_utime = 1'000'000;
  LoopClosureState::Hypothesis h;
  h.candidate = PoseKey{TrajectoryId(3), 11};
  h.key = PoseKey{TrajectoryId(3), 162};
  h.measured = Pose2(5.1, -0.4, 0.02);
  h.covariance = Eigen::Vector3d(4e-4, 5e-4, 3e-5).asDiagonal();
  h.key_utime = 2'000'000;
  h.weak = weak;
  state.kept[TrajectoryId(3)].push_back(h);
  state.wide_searches = 7;
  return state;
}

std::vector<uint8_t> Encode(const LoopClosureState& state, uint32_t version = kSnapshotVersion) {
  ByteWriter w;
  PutLoopClosureState(&w, version, state);
  return w.Take();
}

LoopClosureState Decode(const std::vector<uint8_t>& bytes, uint32_t version, bool* complete) {
  ByteReader r(bytes.data(), bytes.size());
  LoopClosureState state;
  GetLoopClosureState(&r, version, &state);
  *complete = !r.failed() && r.at_end();
  return state;
}

TEST(SourceStateCodecTest, AKeptHypothesisKeepsItsWeakFlag) {
  for (bool weak : {true, false}) {
    bool complete = false;
    const LoopClosureState out =
        Decode(Encode(StateWithOneKeptHypothesis(weak)), kSnapshotVersion, &complete);
    EXPECT_TRUE(complete);
    ASSERT_EQ(out.kept.count(TrajectoryId(3)), 1u);
    ASSERT_EQ(out.kept.at(TrajectoryId(3)).size(), 1u);
    const LoopClosureState::Hypothesis& h = out.kept.at(TrajectoryId(3)).front();
    EXPECT_EQ(h.weak, weak);
    EXPECT_EQ(h.key.index, 162);
    EXPECT_EQ(h.measured.x(), 5.1);
    EXPECT_EQ(h.covariance(1, 1), 5e-4);
    EXPECT_EQ(out.wide_searches, 7);
  }
}

// Version 2 is version 3 without the flag: the one byte where a weak and a strong
// hypothesis's encodings differ.
TEST(SourceStateCodecTest, AVersionTwoStateIsReadWithNoneWeak) {
  const std::vector<uint8_t> weak = Encode(StateWithOneKeptHypothesis(true), 3);
  const std::vector<uint8_t> strong = Encode(StateWithOneKeptHypothesis(false), 3);
  ASSERT_EQ(weak.size(), strong.size());
  std::vector<size_t> differ;
  for (size_t i = 0; i < weak.size(); ++i) {
    if (weak[i] != strong[i]) differ.push_back(i);
  }
  ASSERT_EQ(differ.size(), 1u);
  std::vector<uint8_t> version2 = weak;
  version2.erase(version2.begin() + static_cast<std::ptrdiff_t>(differ.front()));
  // What the encoder writes for a version-2 snapshot (the compatibility tests' bytes).
  EXPECT_EQ(Encode(StateWithOneKeptHypothesis(true), 2), version2);

  bool complete = false;
  const LoopClosureState out = Decode(version2, 2, &complete);
  EXPECT_TRUE(complete);
  ASSERT_EQ(out.kept.at(TrajectoryId(3)).size(), 1u);
  EXPECT_FALSE(out.kept.at(TrajectoryId(3)).front().weak);
  EXPECT_EQ(out.kept.at(TrajectoryId(3)).front().key_utime, 2'000'000);
  EXPECT_EQ(out.wide_searches, 7);
  // Read as version 3, the same bytes end early.
  Decode(version2, 3, &complete);
  EXPECT_FALSE(complete);
}

ScanEncounterState StateWithAWideNearMatch() {
  ScanEncounterState state;
  state.now_utime = 3'000'000;
  ScanEncounterState::Match match;
  match.due_utime = 3'500'000;
  match.key = PoseKey{TrajectoryId(1), 320};
  match.center = PoseKey{TrajectoryId(0), 245};
  match.wide = true;
  match.key_utime = 2'900'000;
  state.matches.push_back(match);
  ScanEncounterCandidateState held;
  held.a = PoseKey{TrajectoryId(0), 245};
  held.b = PoseKey{TrajectoryId(1), 319};
  held.T_a_b = Pose2(-1.12, -2.32, 1.622);
  held.covariance = Eigen::Vector3d(4e-4, 5e-4, 3e-5).asDiagonal();
  held.utime = 2'800'000;
  state.near_held[{TrajectoryId(1), TrajectoryId(0)}].push_back(held);
  state.stats.kept = 1;
  return state;
}

std::vector<uint8_t> Encode(const ScanEncounterState& state, uint32_t version) {
  ByteWriter w;
  PutScanEncounterState(&w, version, state);
  return w.Take();
}

ScanEncounterState DecodeScan(const std::vector<uint8_t>& bytes, uint32_t version, bool* complete) {
  ByteReader r(bytes.data(), bytes.size());
  ScanEncounterState state;
  GetScanEncounterState(&r, version, &state);
  *complete = !r.failed() && r.at_end();
  return state;
}

TEST(SourceStateCodecTest, WideNearMatchesInFlightAndHeldAreKept) {
  bool complete = false;
  const ScanEncounterState out =
      DecodeScan(Encode(StateWithAWideNearMatch(), kSnapshotVersion), kSnapshotVersion, &complete);
  EXPECT_TRUE(complete);
  ASSERT_EQ(out.matches.size(), 1u);
  EXPECT_TRUE(out.matches.front().wide);
  EXPECT_EQ(out.matches.front().key.index, 320);
  const std::pair<TrajectoryId, TrajectoryId> pair{TrajectoryId(1), TrajectoryId(0)};
  ASSERT_EQ(out.near_held.count(pair), 1u);
  ASSERT_EQ(out.near_held.at(pair).size(), 1u);
  const ScanEncounterCandidateState& held = out.near_held.at(pair).front();
  EXPECT_EQ(held.b.index, 319);
  EXPECT_EQ(held.T_a_b.theta(), 1.622);
  EXPECT_EQ(held.covariance(1, 1), 5e-4);
  EXPECT_EQ(held.utime, 2'800'000);
  EXPECT_EQ(out.stats.kept, 1);
}

// A version-4 snapshot knew no wide near search: its state reads with none (the match in
// flight a plain near one), and reading it as version 5 fails rather than misreads.
TEST(SourceStateCodecTest, AVersionFourStateIsReadWithNoWideNearMatches) {
  const std::vector<uint8_t> version4 = Encode(StateWithAWideNearMatch(), 4);
  bool complete = false;
  const ScanEncounterState out = DecodeScan(version4, 4, &complete);
  EXPECT_TRUE(complete);
  ASSERT_EQ(out.matches.size(), 1u);
  EXPECT_FALSE(out.matches.front().wide);
  EXPECT_TRUE(out.near_held.empty());
  DecodeScan(version4, kSnapshotVersion, &complete);
  EXPECT_FALSE(complete);
}

// The pairs caught up after coming into one frame (version 6) are kept; a version-5 state
// reads as not knowing them (the restored source takes the pairs in one frame as caught up).
TEST(SourceStateCodecTest, CaughtUpPairsAreKeptFromVersionSix) {
  ScanEncounterState state = StateWithAWideNearMatch();
  state.near_joined.insert({TrajectoryId(0), TrajectoryId(2)});
  bool complete = false;
  const ScanEncounterState out =
      DecodeScan(Encode(state, kSnapshotVersion), kSnapshotVersion, &complete);
  EXPECT_TRUE(complete);
  EXPECT_TRUE(out.near_joined_known);
  EXPECT_EQ(out.near_joined, state.near_joined);
  const ScanEncounterState old = DecodeScan(Encode(state, 5), 5, &complete);
  EXPECT_TRUE(complete);
  EXPECT_FALSE(old.near_joined_known);
  EXPECT_TRUE(old.near_joined.empty());
}

// Whether a kept candidate is map-verified (version 7) is kept; a version-6 state reads as
// none being.
TEST(SourceStateCodecTest, MapVerifiedKeptCandidatesAreKeptFromVersionSeven) {
  ScanEncounterState state = StateWithAWideNearMatch();
  ScanEncounterState::Kept kept;
  kept.candidate.a = PoseKey{TrajectoryId(0), 5};
  kept.candidate.b = PoseKey{TrajectoryId(1), 85};
  kept.candidate.T_a_b = Pose2(-0.57, -1.13, -0.498);
  kept.support = 1;
  kept.verified = true;
  state.kept[{TrajectoryId(0), TrajectoryId(1)}].push_back(kept);
  bool complete = false;
  const ScanEncounterState out =
      DecodeScan(Encode(state, kSnapshotVersion), kSnapshotVersion, &complete);
  EXPECT_TRUE(complete);
  ASSERT_EQ(out.kept.size(), 1u);
  ASSERT_EQ(out.kept.begin()->second.size(), 1u);
  EXPECT_TRUE(out.kept.begin()->second.front().verified);
  EXPECT_EQ(out.kept.begin()->second.front().support, 1);
  const ScanEncounterState old = DecodeScan(Encode(state, 6), 6, &complete);
  EXPECT_TRUE(complete);
  ASSERT_EQ(old.kept.size(), 1u);
  EXPECT_FALSE(old.kept.begin()->second.front().verified);
}

// The sources' matching budgets (version 9) are kept to the bit: a restored server serves
// the keyframes the uninterrupted one would. A version-8 state reads as having none (the
// restored sources keep fresh budgets), and reading it as version 9 fails.
TEST(SourceStateCodecTest, MatchBudgetsAreKeptFromVersionNine) {
  MatchBudget::State budget;
  budget.tokens = -3.25;  // in debt by part of a keyframe's cost
  budget.last_utime = 41'300'000;
  budget.ledgers[TrajectoryId(4)] = {17.5, 3};
  budget.ledgers[TrajectoryId(9)] = {0.0, 12};
  budget.spent = 1234.5;
  budget.skipped = 77;
  LoopClosureState loop = StateWithOneKeptHypothesis(false);
  loop.budget = budget;
  ScanEncounterState scan = StateWithAWideNearMatch();
  budget.last_utime.reset();
  scan.near_budget = budget;

  bool complete = false;
  const LoopClosureState loop_out = Decode(Encode(loop), kSnapshotVersion, &complete);
  EXPECT_TRUE(complete);
  ASSERT_TRUE(loop_out.budget.has_value());
  EXPECT_EQ(loop_out.budget->tokens, -3.25);
  EXPECT_EQ(loop_out.budget->last_utime, std::optional<int64_t>(41'300'000));
  ASSERT_EQ(loop_out.budget->ledgers.size(), 2u);
  EXPECT_EQ(loop_out.budget->ledgers.at(TrajectoryId(4)).driven_m, 17.5);
  EXPECT_EQ(loop_out.budget->ledgers.at(TrajectoryId(9)).skips, 12);
  EXPECT_EQ(loop_out.budget->spent, 1234.5);
  EXPECT_EQ(loop_out.budget->skipped, 77);
  const ScanEncounterState scan_out =
      DecodeScan(Encode(scan, kSnapshotVersion), kSnapshotVersion, &complete);
  EXPECT_TRUE(complete);
  ASSERT_TRUE(scan_out.near_budget.has_value());
  EXPECT_FALSE(scan_out.near_budget->last_utime.has_value());
  EXPECT_EQ(scan_out.near_budget->ledgers.at(TrajectoryId(4)).skips, 3);

  const std::vector<uint8_t> loop8 = Encode(loop, 8);
  EXPECT_FALSE(Decode(loop8, 8, &complete).budget.has_value());
  EXPECT_TRUE(complete);
  Decode(loop8, kSnapshotVersion, &complete);
  EXPECT_FALSE(complete);
  EXPECT_FALSE(DecodeScan(Encode(scan, 8), 8, &complete).near_budget.has_value());
  EXPECT_TRUE(complete);
}

// A kept candidate's own maps' conflict (version 10: what guides a global search) is kept to
// the bit; a version-9 state reads as not measured (it guides nothing), and reading it as
// version 10 fails.
TEST(SourceStateCodecTest, KeptCandidatesConflictsAreKeptFromVersionTen) {
  ScanEncounterState state = StateWithAWideNearMatch();
  ScanEncounterState::Kept kept;
  kept.candidate.a = PoseKey{TrajectoryId(1), 65};
  kept.candidate.b = PoseKey{TrajectoryId(2), 125};
  kept.verified = true;
  kept.conflict = 0.0129;
  kept.conflict_points = 2791;
  state.kept[{TrajectoryId(1), TrajectoryId(2)}].push_back(kept);
  bool complete = false;
  const ScanEncounterState out =
      DecodeScan(Encode(state, kSnapshotVersion), kSnapshotVersion, &complete);
  EXPECT_TRUE(complete);
  ASSERT_EQ(out.kept.size(), 1u);
  ASSERT_EQ(out.kept.begin()->second.size(), 1u);
  EXPECT_EQ(out.kept.begin()->second.front().conflict, 0.0129);
  EXPECT_EQ(out.kept.begin()->second.front().conflict_points, 2791);
  const std::vector<uint8_t> version9 = Encode(state, 9);
  const ScanEncounterState old = DecodeScan(version9, 9, &complete);
  EXPECT_TRUE(complete);
  ASSERT_EQ(old.kept.size(), 1u);
  EXPECT_TRUE(old.kept.begin()->second.front().verified);
  EXPECT_EQ(old.kept.begin()->second.front().conflict, 1.0);
  EXPECT_EQ(old.kept.begin()->second.front().conflict_points, 0);
  DecodeScan(version9, kSnapshotVersion, &complete);
  EXPECT_FALSE(complete);
}

}  // namespace
}  // namespace anchormap
