#include "common/solver/smoother_state.h"

#include <algorithm>
#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <Eigen/Dense>

#include "common/solver/smoother.h"
#include "tests/testing/random_graph.h"

namespace anchormap {
namespace {

// One Add* call; `update` runs Update() after it (`batch`: BatchOptimize()).
struct Edit {
  enum class Kind { kPose, kBetween, kEncounter } kind = Kind::kPose;
  PoseKey a;
  PoseKey b;
  Pose2 value;  // kPose: the initial guess; else the measurement
  Eigen::Matrix3d covariance = Eigen::Matrix3d::Identity();
  bool update = false;
  bool batch = false;
};

// The solver call after an edit, if any.
Status Solve(const Edit& e, Smoother* smoother) {
  if (e.batch) return smoother->BatchOptimize().status;
  return e.update ? smoother->Update().status : Status::Ok();
}

void Apply(const Edit& e, Smoother* smoother) {
  Status status;
  switch (e.kind) {
    case Edit::Kind::kPose:
      status = smoother->AddPose(e.a, e.value);
      break;
    case Edit::Kind::kBetween:
      status = smoother->AddBetween(e.a, e.b, e.value, e.covariance);
      break;
    case Edit::Kind::kEncounter:
      status = smoother->AddEncounter(e.a, e.b, e.value, e.covariance);
      break;
  }
  ASSERT_TRUE(status.ok()) << status.message();
}

// Four robots, each a random walk with loop closures in its own frame (odometry initial
// guesses), keyframes interleaved; encounters from the truth with an offset per robot
// (anchors appear in two groups, which then merge: a partial merge step), an update after
// each step (a batch step at step 8).
std::vector<Edit> Mission() {
  const int kPoses = 60;
  std::vector<PoseGraph> graphs;
  const Pose2 offsets[] = {Pose2(0, 0, 0), Pose2(3, -2, 0.7), Pose2(-4, 1, -1.2), Pose2(1, 5, 2.0)};
  for (uint32_t r = 0; r < 4; ++r) {
    testing::RandomGraphOptions options;
    options.poses = kPoses;
    options.loop_closures = 12;
    options.seed = 40 + r;
    graphs.push_back(testing::RandomGraph(options));
  }
  const Eigen::Matrix3d odometry_cov = Eigen::Vector3d(2.5e-3, 2.5e-3, 4e-4).asDiagonal();
  std::vector<Edit> edits;
  std::vector<Pose2> dead_reckoning(4);
  for (int i = 0; i < kPoses; ++i) {
    for (int r = 0; r < 4; ++r) {
      const TrajectoryId t(r);
      const PoseGraph& g = graphs[static_cast<size_t>(r)];
      if (i > 0) dead_reckoning[r] = Compose(dead_reckoning[r], g.edges[i - 1].measured_T_from_to);
      edits.push_back({Edit::Kind::kPose, {t, i}, {t, i}, dead_reckoning[r], odometry_cov, false});
      if (i > 0) {
        edits.push_back({Edit::Kind::kBetween,
                         {t, i - 1},
                         {t, i},
                         g.edges[i - 1].measured_T_from_to,
                         g.edges[i - 1].information.inverse(),
                         false});
      }
      for (size_t e = kPoses - 1; e < g.edges.size(); ++e) {
        if (g.edges[e].to != i) continue;
        edits.push_back({Edit::Kind::kBetween,
                         {t, static_cast<int32_t>(g.edges[e].from)},
                         {t, i},
                         g.edges[e].measured_T_from_to,
                         g.edges[e].information.inverse(),
                         false});
      }
    }
    // Encounters: 0-1 from step 10, 2-3 from step 15 (two groups), 1-2 from step 30 (they
    // merge), 0-3 from step 45.
    auto encounter = [&](int ra, int rb) {
      const Pose2 truth_a = Compose(offsets[ra], graphs[ra].vertices[i].pose);
      const Pose2 truth_b = Compose(offsets[rb], graphs[rb].vertices[i].pose);
      const Pose2 seen = Between(truth_a, truth_b);
      edits.push_back({Edit::Kind::kEncounter,
                       {TrajectoryId(ra), i},
                       {TrajectoryId(rb), i},
                       Pose2(seen.x() + 0.01, seen.y() - 0.01, seen.theta() + 0.002),
                       Eigen::Vector3d(4e-3, 4e-3, 1e-3).asDiagonal(),
                       false});
    };
    if (i >= 10 && i % 5 == 0) encounter(0, 1);
    if (i >= 15 && i % 5 == 0) encounter(2, 3);
    if (i >= 30 && i % 7 == 0) encounter(1, 2);
    if (i >= 45 && i % 6 == 0) encounter(0, 3);
    edits.back().update = true;
    // As the server's final step, once: later growth then triggers batch steps on fill.
    edits.back().batch = i == 8;
  }
  return edits;
}

Eigen::Vector3d Bits(const Pose2& p) { return Eigen::Vector3d(p.x(), p.y(), p.theta()); }

// Everything the two smoothers hold, to the bit.
void ExpectSameSmoother(const Smoother& a, const Smoother& b) {
  const Smoother::LinearSystem x = a.LinearSystemForTesting();
  const Smoother::LinearSystem y = b.LinearSystemForTesting();
  ASSERT_EQ(x.keys, y.keys);
  ASSERT_EQ(x.rows.size(), y.rows.size());
  for (size_t p = 0; p < x.rows.size(); ++p) {
    EXPECT_EQ(Bits(x.linearization[p]), Bits(y.linearization[p])) << p;
    EXPECT_EQ(x.delta[p], y.delta[p]) << p;
    EXPECT_EQ(x.rows[p].diagonal, y.rows[p].diagonal) << p;
    EXPECT_EQ(x.rows[p].rhs, y.rows[p].rhs) << p;
    ASSERT_EQ(x.rows[p].right.size(), y.rows[p].right.size()) << p;
    for (size_t k = 0; k < x.rows[p].right.size(); ++k) {
      EXPECT_EQ(x.rows[p].right[k].first, y.rows[p].right[k].first);
      EXPECT_EQ(x.rows[p].right[k].second, y.rows[p].right[k].second);
    }
  }
  for (TrajectoryId t : a.Trajectories()) {
    for (int i = 0; a.HasPose({t, i}); ++i) {
      EXPECT_EQ(Bits(a.GlobalPose({t, i})), Bits(b.GlobalPose({t, i})));
    }
  }
  const SmootherStats& s = a.stats();
  const SmootherStats& u = b.stats();
  EXPECT_EQ(s.updates, u.updates);
  EXPECT_EQ(s.batch_steps, u.batch_steps);
  EXPECT_EQ(s.batch_steps_on_fill, u.batch_steps_on_fill);
  EXPECT_EQ(s.partial_relinearizations, u.partial_relinearizations);
  EXPECT_EQ(s.partial_merges, u.partial_merges);
  EXPECT_EQ(s.givens_block_rows, u.givens_block_rows);
  EXPECT_EQ(s.rows_reeliminated, u.rows_reeliminated);
  EXPECT_EQ(s.correction_steps, u.correction_steps);
  EXPECT_EQ(s.correction_skips, u.correction_skips);
  const SmootherState sa = a.ExportState();
  const SmootherState sb = b.ExportState();
  EXPECT_EQ(sa.uncorrected_factors, sb.uncorrected_factors);
  ASSERT_EQ(sa.local_pass_values.size(), sb.local_pass_values.size());
  for (size_t k = 0; k < sa.local_pass_values.size(); ++k) {
    EXPECT_EQ(sa.local_pass_values[k].variable, sb.local_pass_values[k].variable);
    EXPECT_EQ(Bits(sa.local_pass_values[k].value), Bits(sb.local_pass_values[k].value));
  }
  EXPECT_EQ(sa.local_moved_factors, sb.local_moved_factors);
  EXPECT_EQ(sa.local_seeds_from, sb.local_seeds_from);
  EXPECT_EQ(s.nnz_r, u.nnz_r);
  EXPECT_EQ(a.Chi2(), b.Chi2());
}

// A smoother given the same Add* calls and the exported state continues exactly as the
// exporting one: after the remaining edits and updates, the same R, d, delta,
// linearisation points, estimate and step counters, to the bit (the server's options:
// partial relinearisation, partial merges, batch steps on fill). States are taken between
// updates and with measurements pending (added, not yet folded in).
// `with_local_moves`: how many of the exported states held local corrections' moves.
void ExpectImportedStatesContinueExactly(const SmootherOptions& options, int* with_local_moves) {
  const std::vector<Edit> edits = Mission();
  Smoother live(options);
  std::vector<std::pair<size_t, SmootherState>> exported;  // (edits applied, state)
  const size_t n = edits.size();
  const std::vector<size_t> cuts = {n / 6, n / 3 + 1, n / 2, n / 2 + 1, 2 * n / 3, 5 * n / 6 + 1};
  for (size_t e = 0; e < n; ++e) {
    Apply(edits[e], &live);
    ASSERT_TRUE(Solve(edits[e], &live).ok());
    if (std::find(cuts.begin(), cuts.end(), e) != cuts.end()) {
      exported.emplace_back(e + 1, live.ExportState());
    }
  }
  ASSERT_GT(live.stats().partial_merges, 0);  // the groups merged by partial steps
  ASSERT_GT(live.stats().partial_relinearizations, 0);
  ASSERT_GT(live.stats().batch_steps_on_fill, 0);
  if (options.correction_tolerance > 0) {
    ASSERT_GT(live.stats().correction_steps, 0);
  }

  int with_pending = 0;
  *with_local_moves = 0;
  for (auto& [cut, state] : exported) {
    SCOPED_TRACE("state after edit " + std::to_string(cut));
    with_pending += state.pending_factors.empty() ? 0 : 1;
    *with_local_moves += state.local_pass_values.empty() ? 0 : 1;
    Smoother restored(options);
    for (size_t e = 0; e < cut; ++e) Apply(edits[e], &restored);
    ASSERT_TRUE(restored.ImportState(state).ok());
    const SmootherState reexported = restored.ExportState();
    EXPECT_EQ(reexported.r.column_rows, state.r.column_rows);
    EXPECT_EQ(reexported.pending_factors, state.pending_factors);
    EXPECT_EQ(reexported.grounded, state.grounded);
    EXPECT_EQ(reexported.uncorrected_factors, state.uncorrected_factors);
    EXPECT_EQ(reexported.local_moved_factors, state.local_moved_factors);
    EXPECT_EQ(reexported.local_seeds_from, state.local_seeds_from);
    for (size_t e = cut; e < edits.size(); ++e) {
      Apply(edits[e], &restored);
      ASSERT_TRUE(Solve(edits[e], &restored).ok());
    }
    ExpectSameSmoother(live, restored);
  }
  EXPECT_GT(with_pending, 0);
}

TEST(SmootherStateTest, AnImportedStateContinuesExactlyAsTheExportingSmoother) {
  int with_local_moves = 0;
  ExpectImportedStatesContinueExactly(ServerModeOptions(), &with_local_moves);
}

TEST(SmootherStateTest, AnImportedStateContinuesExactlyWithTheConjugateGradientCorrection) {
  // The estimate is then theta + delta + correction with the correction carried across
  // updates: it must be in the state too. (The whole map's path only: the local
  // correction has tests of its own below.)
  SmootherOptions options = ServerModeWithCorrectionOptions();
  options.correction_local_hops = 0;
  int with_local_moves = 0;
  ExpectImportedStatesContinueExactly(options, &with_local_moves);
  EXPECT_EQ(with_local_moves, 0);
}

TEST(SmootherStateTest, AnImportedStateContinuesExactlyWithTheLocalCorrection) {
  // correction_local_hops: the values local steps moved since the last gradient pass and
  // the factors that see them enter the skip test's bound until the next whole-map
  // correction, so they are state too (without them the restored smoother's bound leaves
  // their terms out and it skips where the exporting one corrects).
  SmootherOptions options = ServerModeWithCorrectionOptions();
  options.correction_local_hops = 4;
  int with_local_moves = 0;
  ExpectImportedStatesContinueExactly(options, &with_local_moves);
  EXPECT_GT(with_local_moves, 0);
}

// At every update of the mission run by `live` (built with `options`), a smoother restored
// from the state just before the update makes the same update to the bit; all 60 updates
// are compared. `marked` counts the states before them for which `mark` holds (so that a
// caller can assert the case it is about was reached).
void ExpectEveryUpdateContinuesFromTheStateBeforeIt(
    const SmootherOptions& options, Smoother* live,
    const std::function<bool(const SmootherState&)>& mark, int* marked) {
  const std::vector<Edit> edits = Mission();
  int compared = 0;
  *marked = 0;
  for (size_t e = 0; e < edits.size(); ++e) {
    Apply(edits[e], live);
    if (!edits[e].update && !edits[e].batch) continue;
    const SmootherState before = live->ExportState();
    *marked += mark(before) ? 1 : 0;
    ASSERT_TRUE(Solve(edits[e], live).ok());
    Smoother restored(options);
    for (size_t k = 0; k <= e; ++k) Apply(edits[k], &restored);
    ASSERT_TRUE(restored.ImportState(before).ok());
    ASSERT_TRUE(Solve(edits[e], &restored).ok());
    SCOPED_TRACE("update after edit " + std::to_string(e));
    ExpectSameSmoother(*live, restored);
    ++compared;
  }
  EXPECT_EQ(compared, 60);
}

// The correction's gradient passes reuse the factors linearised at the estimate
// (linearization_cache.h), which is not in the state: at every update of the mission, a
// smoother restored from the state just before it (whose first pass linearises every
// factor) makes the same update to the bit.
TEST(SmootherStateTest, EveryCorrectedUpdateIsWhatAFullGradientPassGives) {
  SmootherOptions options = ServerModeWithCorrectionOptions();
  options.correction_local_hops = 0;  // every correction over the whole map
  Smoother live(options);
  int with_uncorrected = 0;  // states after a skipped correction: its factors' bound held
  ExpectEveryUpdateContinuesFromTheStateBeforeIt(
      options, &live, [](const SmootherState& s) { return !s.uncorrected_factors.empty(); },
      &with_uncorrected);
  EXPECT_GT(with_uncorrected, 0);
  // The cache saved work: not every pass linearised every factor.
  const CorrectionWork work = live.correction_work();
  EXPECT_GT(work.gradient_passes, 60);
  EXPECT_LT(work.factors_linearized, work.gradient_passes * live.stats().factors * 3 / 4);
}

// correction_local_hops, at every update of the mission: a smoother restored from the
// state just before it makes the same update to the bit, including those whose skip test
// must add the change of the factors that earlier local steps moved since the last pass.
TEST(SmootherStateTest, EveryUpdateAfterLocalCorrectionsContinuesExactlyFromTheState) {
  SmootherOptions options = ServerModeWithCorrectionOptions();
  options.correction_local_hops = 4;
  Smoother live(options);
  int with_local_moves = 0;
  ExpectEveryUpdateContinuesFromTheStateBeforeIt(
      options, &live, [](const SmootherState& s) { return !s.local_pass_values.empty(); },
      &with_local_moves);
  EXPECT_GT(with_local_moves, 5);
}

TEST(SmootherStateTest, AStateOfAnotherGraphIsRefusedAndChangesNothing) {
  const std::vector<Edit> edits = Mission();
  Smoother live(ServerModeOptions());
  for (size_t e = 0; e < 100; ++e) {
    Apply(edits[e], &live);
    ASSERT_TRUE(Solve(edits[e], &live).ok());
  }
  Smoother shorter(ServerModeOptions());
  for (size_t e = 0; e < 90; ++e) Apply(edits[e], &shorter);
  const Status refused = shorter.ImportState(live.ExportState());
  EXPECT_FALSE(refused.ok());
  EXPECT_EQ(refused.code(), ErrorCode::kInvalidArgument);
  EXPECT_EQ(shorter.stats().updates, 0);
  EXPECT_TRUE(shorter.Update().status.ok());  // still the fresh smoother it was
}

// GlobalTrajectory (the map publication's read of every keyframe, the anchor looked up once per
// trajectory) gives every keyframe's GlobalPose to the bit, for trajectories anchored and not,
// with the correction carried across updates.
TEST(SmootherStateTest, GlobalTrajectoryIsEveryKeyframesGlobalPose) {
  SmootherOptions options = ServerModeOptions();
  options.correction_tolerance = 1e-4;
  options.correction_cg_iterations = 50;
  const std::vector<Edit> edits = Mission();
  Smoother smoother(options);
  int anchored = 0, unanchored = 0;
  for (size_t e = 0; e < edits.size(); ++e) {
    Apply(edits[e], &smoother);
    ASSERT_TRUE(Solve(edits[e], &smoother).ok());
    if (e % 7 != 0) continue;
    for (TrajectoryId t : smoother.Trajectories()) {
      const std::vector<Pose2> poses = smoother.GlobalTrajectory(t);
      ASSERT_EQ(static_cast<int>(poses.size()), smoother.NumPoses(t));
      for (int32_t i = 0; i < smoother.NumPoses(t); ++i) {
        EXPECT_EQ(Bits(poses[static_cast<size_t>(i)]), Bits(smoother.GlobalPose({t, i})));
      }
      (smoother.IsAnchored(t) ? anchored : unanchored) += 1;
    }
  }
  EXPECT_GT(anchored, 0);
  EXPECT_GT(unanchored, 0);
}

}  // namespace
}  // namespace anchormap
