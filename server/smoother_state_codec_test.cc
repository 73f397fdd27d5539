// The smoother's state codec: from version 8 the factors since the last correction are
// written (the skip test sums their gradient); in an older format there is no room for
// them, so the skip test's bound is written as infinite when there are any (the restored
// smoother corrects at its next update instead of skipping on a bound that leaves them out).

#include "server/smoother_state_codec.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "common/geometry/angle.h"
#include "common/geometry/pose2.h"
#include "common/solver/smoother.h"
#include "common/solver/smoother_options.h"
#include "server/snapshot_codec.h"

namespace anchormap {
namespace {

SmootherState Decode(const std::vector<uint8_t>& bytes, uint32_t version, bool* complete) {
  ByteReader r(bytes.data(), bytes.size());
  SmootherState state;
  GetSmootherState(&r, version, &state);
  *complete = !r.failed() && r.at_end();
  return state;
}

std::vector<uint8_t> Encode(const SmootherState& state, uint32_t version) {
  ByteWriter w;
  PutSmootherState(&w, version, state);
  return w.Take();
}

TEST(SmootherStateCodecTest, TheUncorrectedFactorsAreKeptOrTheirBoundIsInfinite) {
  SmootherState state;
  state.correction_converged = true;
  state.innovation = 0.25;
  state.uncorrected_factors = {12, 13, 40};
  bool complete = false;
  SmootherState out = Decode(Encode(state, kSnapshotVersion), kSnapshotVersion, &complete);
  EXPECT_TRUE(complete);
  EXPECT_EQ(out.innovation, 0.25);
  EXPECT_EQ(out.uncorrected_factors, state.uncorrected_factors);

  out = Decode(Encode(state, 7), 7, &complete);
  EXPECT_TRUE(complete);
  EXPECT_TRUE(std::isinf(out.innovation));
  EXPECT_TRUE(out.uncorrected_factors.empty());

  // None to leave out: the bound as it is.
  state.uncorrected_factors.clear();
  out = Decode(Encode(state, 7), 7, &complete);
  EXPECT_TRUE(complete);
  EXPECT_EQ(out.innovation, 0.25);
}

// From version 11 the local corrections' moves are written (the skip test adds the moved
// factors' change since the last pass); an older format has no room for them and writes the
// bound as infinite when there are any.
TEST(SmootherStateCodecTest, TheLocalMovesAreKeptOrTheirBoundIsInfinite) {
  SmootherState state;
  state.correction_converged = true;
  state.innovation = 0.25;
  state.uncorrected_factors = {12, 13, 40};
  state.local_pass_values = {{7, Pose2(1.5, -2.25, 0.125)}, {3, Pose2(-0.5, 4.0, -3.0)}};
  state.local_moved_factors = {2, 9};
  state.local_seeds_from = 2;
  bool complete = false;
  SmootherState out = Decode(Encode(state, kSnapshotVersion), kSnapshotVersion, &complete);
  EXPECT_TRUE(complete);
  EXPECT_EQ(out.innovation, 0.25);
  ASSERT_EQ(out.local_pass_values.size(), 2u);
  EXPECT_EQ(out.local_pass_values[0].variable, 7);
  EXPECT_EQ(out.local_pass_values[0].value.y(), -2.25);
  EXPECT_EQ(out.local_pass_values[1].variable, 3);
  EXPECT_EQ(out.local_pass_values[1].value.theta(), -3.0);
  EXPECT_EQ(out.local_moved_factors, state.local_moved_factors);
  EXPECT_EQ(out.local_seeds_from, 2);

  out = Decode(Encode(state, 10), 10, &complete);
  EXPECT_TRUE(complete);
  EXPECT_TRUE(std::isinf(out.innovation));
  EXPECT_EQ(out.uncorrected_factors, state.uncorrected_factors);
  EXPECT_TRUE(out.local_pass_values.empty());
  EXPECT_TRUE(out.local_moved_factors.empty());
  EXPECT_EQ(out.local_seeds_from, 0);

  // No local move to leave out: the bound as it is.
  state.local_pass_values.clear();
  state.local_moved_factors.clear();
  state.local_seeds_from = 0;
  out = Decode(Encode(state, 10), 10, &complete);
  EXPECT_TRUE(complete);
  EXPECT_EQ(out.innovation, 0.25);
}

// --- The reduced graph's aliases (snapshot version 12) ---

// One Add* call of the fold's mission; `update` runs Update() after it.
struct AliasEdit {
  enum class Kind { kPose, kBetween, kEncounter, kAlias } kind = Kind::kPose;
  PoseKey a;  // kAlias: the keyframe
  PoseKey b;  // kAlias: its node
  Pose2 value;
  Eigen::Matrix3d covariance = Eigen::Matrix3d::Identity();
  bool update = false;
};

Status Apply(const AliasEdit& e, Smoother* smoother) {
  switch (e.kind) {
    case AliasEdit::Kind::kPose:
      return smoother->AddPose(e.a, e.value);
    case AliasEdit::Kind::kBetween:
      return smoother->AddBetween(e.a, e.b, e.value, e.covariance);
    case AliasEdit::Kind::kEncounter:
      return smoother->AddEncounter(e.a, e.b, e.value, e.covariance);
    case AliasEdit::Kind::kAlias:
      return smoother->AddAlias(e.a, e.b, e.value, e.covariance);
  }
  return Status::Ok();
}

constexpr int kLapPoses = 12;
constexpr int kLaps = 4;

// R0 and R1 drive one circle (radius 3 m, 12 keyframes a lap) half a lap apart, an encounter
// at their third keyframes. The first lap makes variables; then R0's keyframes fold onto its
// own first-lap nodes, R1's onto R0's nodes at the same place (across trajectories), except
// R1's first four keyframes of the third lap: after a fold onto R0, a node borrowed from R0
// (the server's rule), its keyframe aliased onto it with the identity. Odometry between
// consecutive keyframes (mapped onto the nodes), a loop closure of R0 between two keyframes
// folded onto one node (inside it: no factor) and one from the last lap to the first; an update
// after each step.
std::vector<AliasEdit> FoldMission() {
  const TrajectoryId r0(0), r1(1);
  auto truth = [](int robot, int k) {
    const double angle = 2.0 * kPi * (k % kLapPoses) / kLapPoses + (robot == 0 ? 0.0 : kPi);
    return Pose2(3.0 * std::cos(angle), 3.0 * std::sin(angle), angle + kPi / 2);
  };
  // A small deterministic error on every measurement.
  auto noisy = [](const Pose2& p, int salt) {
    return Pose2(p.x() + 0.01 * std::sin(1.3 * salt), p.y() + 0.01 * std::cos(0.7 * salt),
                 p.theta() + 0.003 * std::sin(2.1 * salt));
  };
  const Eigen::Matrix3d odometry = Eigen::Vector3d(4e-4, 4e-4, 1e-4).asDiagonal();
  const Eigen::Matrix3d fold = Eigen::Vector3d(1e-4, 1e-4, 2e-5).asDiagonal();
  std::vector<AliasEdit> edits;
  int borrowed = 0;
  bool r1_on_r0 = false;  // R1's last keyframe folded onto R0's node
  for (int k = 0; k < kLaps * kLapPoses; ++k) {
    const int place = k % kLapPoses;
    for (int robot = 0; robot < 2; ++robot) {
      const TrajectoryId t = robot == 0 ? r0 : r1;
      const PoseKey key{t, k};
      const Pose2 local = Between(truth(robot, 0), truth(robot, k));
      if (k < kLapPoses) {
        edits.push_back({AliasEdit::Kind::kPose, key, key, noisy(local, 7 * k + robot)});
      } else if (robot == 1 && r1_on_r0 && k >= 2 * kLapPoses && place < 4) {
        const PoseKey node{r0, kBorrowedNodeIndexBase + borrowed++};
        edits.push_back(
            {AliasEdit::Kind::kPose, node, node, noisy(Between(truth(0, 0), truth(1, k)), 3 * k)});
        edits.push_back(
            {AliasEdit::Kind::kAlias, key, node, Pose2(), Eigen::Matrix3d::Zero(), false});
        r1_on_r0 = false;
      } else {
        // R0's node at this place: R0's own keyframe, or for R1 the one half a lap on.
        const int node_index = robot == 0 ? place : (place + kLapPoses / 2) % kLapPoses;
        edits.push_back({AliasEdit::Kind::kAlias, key, PoseKey{r0, node_index},
                         noisy(Pose2(), 11 * k + robot), fold, false});
        if (robot == 1) r1_on_r0 = true;
      }
      if (k > 0) {
        edits.push_back({AliasEdit::Kind::kBetween, PoseKey{t, k - 1}, key,
                         noisy(Between(truth(robot, k - 1), truth(robot, k)), 5 * k + robot),
                         odometry, false});
      }
    }
    if (k == 2) {
      edits.push_back({AliasEdit::Kind::kEncounter, PoseKey{r0, 2}, PoseKey{r1, 2},
                       noisy(Between(truth(0, 2), truth(1, 2)), 99),
                       Eigen::Vector3d(2.5e-3, 2.5e-3, 4e-4).asDiagonal(), false});
    }
    if (k == 2 * kLapPoses + 5) {  // R0's keyframes 17 and 29 are both on node 5
      edits.push_back({AliasEdit::Kind::kBetween, PoseKey{r0, kLapPoses + 5}, PoseKey{r0, k},
                       noisy(Pose2(), 42), odometry, false});
    }
    if (k == 3 * kLapPoses + 8) {  // a closure onto the first lap
      edits.push_back({AliasEdit::Kind::kBetween, PoseKey{r0, 3}, PoseKey{r0, k},
                       noisy(Between(truth(0, 3), truth(0, k)), 43), odometry, false});
    }
    edits.back().update = true;
  }
  return edits;
}

Eigen::Vector3d Bits(const Pose2& p) { return Eigen::Vector3d(p.x(), p.y(), p.theta()); }

// Every key's pose and alias, and covariance queries on aliases and variables, to the bit.
void ExpectSameQueries(Smoother* a, Smoother* b) {
  EXPECT_EQ(a->NumAliases(), b->NumAliases());
  EXPECT_EQ(a->measurements_inside_nodes(), b->measurements_inside_nodes());
  EXPECT_EQ(a->NextBorrowedNode(TrajectoryId(0)), b->NextBorrowedNode(TrajectoryId(0)));
  EXPECT_EQ(a->NextBorrowedNode(TrajectoryId(1)), b->NextBorrowedNode(TrajectoryId(1)));
  EXPECT_EQ(a->stats().updates, b->stats().updates);
  std::vector<PoseKey> keys;
  for (const TrajectoryId t : a->Trajectories()) {
    for (int i = 0; a->HasPose({t, i}); ++i) keys.push_back({t, i});
    for (int i = kBorrowedNodeIndexBase; a->HasPose({t, i}); ++i) keys.push_back({t, i});
  }
  ASSERT_GT(keys.size(), 2u);
  for (const PoseKey& key : keys) {
    SCOPED_TRACE(Key(key).ToString());
    ASSERT_TRUE(b->HasPose(key));
    EXPECT_EQ(Bits(a->GlobalPose(key)), Bits(b->GlobalPose(key)));
    EXPECT_EQ(Bits(a->FramePose(key)), Bits(b->FramePose(key)));
    const PoseAlias* x = a->FindAlias(key);
    const PoseAlias* y = b->FindAlias(key);
    ASSERT_EQ(x == nullptr, y == nullptr);
    if (x != nullptr) {
      EXPECT_EQ(x->node, y->node);
      EXPECT_EQ(Bits(x->T_node_key), Bits(y->T_node_key));
      EXPECT_EQ(x->covariance, y->covariance);
    }
    ASSERT_EQ(a->HasCovariance(key), b->HasCovariance(key));
    if (a->IsSolved(key)) {
      EXPECT_EQ(a->MarginalCovariance(key), b->MarginalCovariance(key));
      // The relative pose of the key and the mission's first keyframe (an alias's terms on
      // its node, and the anchors across trajectories).
      const PoseKey first{TrajectoryId(0), 0};
      if (!(key == first) && a->IsSolved(first)) {
        const std::vector<Key> pair = {first, key};
        const std::vector<Eigen::Matrix3d> jacobians = {-Eigen::Matrix3d::Identity(),
                                                        Eigen::Matrix3d::Identity()};
        EXPECT_EQ(a->ProjectedCovariance(pair, jacobians), b->ProjectedCovariance(pair, jacobians));
      }
    }
  }
}

// A smoother with aliases (within and across trajectories), borrowed nodes and a measurement
// inside one node: its state through the snapshot's bytes, imported into a smoother given the
// same Add* calls, answers every pose and covariance query as the exporting one, and every
// update after it is the same to the bit.
TEST(SmootherStateCodecTest, ASmootherWithAliasesContinuesExactlyThroughTheBytes) {
  const std::vector<AliasEdit> edits = FoldMission();
  const SmootherOptions options = ServerModeWithCorrectionOptions();
  Smoother live(options);
  const size_t n = edits.size();
  // Between updates and with edits pending (a fold, a borrowed node, odometry not yet solved).
  const std::vector<size_t> cuts = {n / 3, n / 2, n / 2 + 1, 2 * n / 3, 5 * n / 6 + 1};
  std::vector<std::pair<size_t, std::vector<uint8_t>>> states;  // (edits applied, bytes)
  for (size_t e = 0; e < n; ++e) {
    ASSERT_TRUE(Apply(edits[e], &live).ok()) << e;
    if (edits[e].update) {
      ASSERT_TRUE(live.Update().status.ok()) << e;
    }
    if (std::find(cuts.begin(), cuts.end(), e + 1) != cuts.end()) {
      states.emplace_back(e + 1, Encode(live.ExportState(), kSnapshotVersion));
    }
  }
  // The mission has what it is about.
  EXPECT_EQ(live.NextBorrowedNode(TrajectoryId(0)).index, kBorrowedNodeIndexBase + 4);
  EXPECT_EQ(live.measurements_inside_nodes(), 1);
  EXPECT_EQ(live.NumAliases(), 2 * (kLaps - 1) * kLapPoses);
  ASSERT_EQ(states.size(), cuts.size());

  // Replayed from the start, each state: the same queries at once, the same after each update.
  for (const auto& [cut, bytes] : states) {
    SCOPED_TRACE("state after edit " + std::to_string(cut));
    bool complete = false;
    SmootherState state = Decode(bytes, kSnapshotVersion, &complete);
    ASSERT_TRUE(complete);
    Smoother original(options), restored(options);
    for (size_t e = 0; e < cut; ++e) {
      ASSERT_TRUE(Apply(edits[e], &original).ok());
      if (edits[e].update) {
        ASSERT_TRUE(original.Update().status.ok());
      }
      ASSERT_TRUE(Apply(edits[e], &restored).ok());
    }
    EXPECT_EQ(state.aliases, original.NumAliases());
    const Status imported = restored.ImportState(std::move(state));
    ASSERT_TRUE(imported.ok()) << imported.message();
    ExpectSameQueries(&original, &restored);
    EXPECT_TRUE(Encode(restored.ExportState(), kSnapshotVersion) == bytes);
    for (size_t e = cut; e < n; ++e) {
      ASSERT_TRUE(Apply(edits[e], &original).ok());
      ASSERT_TRUE(Apply(edits[e], &restored).ok());
      if (!edits[e].update) continue;
      const UpdateResult x = original.Update();
      const UpdateResult y = restored.Update();
      ASSERT_TRUE(x.status.ok() && y.status.ok());
      EXPECT_EQ(x.batch_step, y.batch_step);
      EXPECT_EQ(x.factors_added, y.factors_added);
      EXPECT_EQ(x.relinearized, y.relinearized);
      ExpectSameQueries(&original, &restored);
    }
    EXPECT_TRUE(Encode(restored.ExportState(), kSnapshotVersion) ==
                Encode(live.ExportState(), kSnapshotVersion));
  }
}

// The state holds the aliases' counts: a smoother given the same variables and factors but not
// the same alias graph (here without the closure between two keyframes folded onto one node:
// no factor either way) refuses it.
TEST(SmootherStateCodecTest, AStateOfOtherAliasesIsRefused) {
  const std::vector<AliasEdit> edits = FoldMission();
  Smoother live(ServerModeOptions()), other(ServerModeOptions());
  // Up to and with the closure inside node 5 (R0's keyframe 29 folded onto it).
  size_t closure = 0;
  for (size_t e = 0; e < edits.size() && closure == 0; ++e) {
    ASSERT_TRUE(Apply(edits[e], &live).ok());
    if (edits[e].kind == AliasEdit::Kind::kBetween && edits[e].b.index == 2 * kLapPoses + 5 &&
        edits[e].a.index == kLapPoses + 5) {
      closure = e;
    }
  }
  ASSERT_GT(closure, 0u);
  ASSERT_EQ(live.measurements_inside_nodes(), 1);
  for (size_t e = 0; e < closure; ++e) ASSERT_TRUE(Apply(edits[e], &other).ok());
  ASSERT_EQ(live.stats().variables, other.stats().variables);
  const Status refused = other.ImportState(live.ExportState());
  EXPECT_FALSE(refused.ok());
  EXPECT_EQ(refused.code(), ErrorCode::kInvalidArgument);
  EXPECT_NE(refused.message().find("aliases"), std::string::npos);
  // Read from an older format the counts are 0 (no server folded then).
  bool complete = false;
  const SmootherState old = Decode(Encode(live.ExportState(), 11), 11, &complete);
  EXPECT_TRUE(complete);
  EXPECT_EQ(old.aliases, 0);
  EXPECT_EQ(old.measurements_inside_nodes, 0);
}

}  // namespace
}  // namespace anchormap
