#include "server/keyframe_fold.h"

#include <cmath>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include <gtest/gtest.h>

#include "tests/scan_testing/scan_scenarios.h"

namespace anchormap {
namespace {

using testing::DriveKeyframes;
using testing::LoopWorld;
using testing::OdometryNoise;

constexpr double kPiOver3 = 1.0471975511965976;

// A trajectory table and smoother fed as MappingServer feeds them: every keyframe a node
// unless asked to Try a fold.
class KeyframeFoldTest : public ::testing::Test {
 protected:
  // R1 drives 5 m east along LoopWorld's south corridor (y = 2), a keyframe every 0.5 m:
  // eleven nodes at x = 2.5, 3.0, ..., 7.5.
  void SetUp() override {
    for (int i = 0; i <= 10; ++i) path_.push_back(Pose2(2.5 + 0.5 * i, 2.0, 0.0));
    for (const Keyframe& k : Drive(path_, "R1", 1)) ASSERT_TRUE(AddNode(k));
  }

  std::vector<Keyframe> Drive(const std::vector<Pose2>& path, const std::string& robot,
                              int64_t id) const {
    return DriveKeyframes(world_, path, robot, id, 1'000'000, OdometryNoise{0.005, 0.002}, 7);
  }

  bool AddNode(const Keyframe& keyframe) {
    std::vector<AdmittedKeyframe> admitted;
    if (!table_.Offer(keyframe, &admitted).ok() || admitted.size() != 1) return false;
    const AdmittedKeyframe& a = admitted.front();
    const Pose2 initial =
        a.previous ? Compose(smoother_.FramePose(*a.previous), a.T_previous_this) : a.T_local_pose;
    if (!smoother_.AddPose(a.key, initial).ok()) return false;
    if (a.previous &&
        !smoother_.AddBetween(*a.previous, a.key, a.T_previous_this, a.T_previous_this_covariance)
             .ok()) {
      return false;
    }
    folder_.AddNode(a.key, a.key, smoother_);
    return smoother_.Update().status.ok();
  }

  // R1's drive on to keyframe 11, which folds onto node 3 (x = 4.0), and keyframe 12, again
  // onto node 3.
  std::vector<Keyframe> TwiceOntoNodeThree() const {
    std::vector<Pose2> path = path_;
    path.push_back(Pose2(4.2, 2.0, 0.087));
    path.push_back(Pose2(4.1, 2.0, 0.05));
    return Drive(path, "R1", 1);
  }

  // `folder` with R1's keyframes 0-10 as its nodes.
  void AddPathNodes(KeyframeFolder* folder) {
    for (int32_t i = 0; i <= 10; ++i) {
      folder->AddNode({TrajectoryId(0), i}, {TrajectoryId(0), i}, smoother_);
    }
  }

  // R1's keyframe 11, 0.2 m past node 10 (its predecessor), admitted by the table.
  std::optional<AdmittedKeyframe> PastTheLastNode() {
    std::vector<Pose2> path = path_;
    path.push_back(Pose2(7.7, 2.0, 0.0));
    std::vector<AdmittedKeyframe> admitted;
    if (!table_.Offer(Drive(path, "R1", 1).back(), &admitted).ok() || admitted.size() != 1 ||
        !admitted.front().previous) {
      return std::nullopt;
    }
    return admitted.front();
  }

  // Where `folder` folds the admitted keyframe `a`.
  std::optional<KeyframeFold> Decide(KeyframeFolder* folder, const AdmittedKeyframe& a) {
    return folder->Decide(a.key, *a.previous, a.T_previous_this, a.T_previous_this_covariance,
                          table_, &smoother_);
  }

  // Offers `keyframe` and asks where it folds.
  std::optional<KeyframeFold> Try(const Keyframe& keyframe) {
    std::vector<AdmittedKeyframe> admitted;
    EXPECT_TRUE(table_.Offer(keyframe, &admitted).ok());
    EXPECT_EQ(admitted.size(), 1u);
    const AdmittedKeyframe& a = admitted.front();
    return folder_.Decide(a.key, *a.previous, a.T_previous_this, a.T_previous_this_covariance,
                          table_, &smoother_);
  }

  // R1's keyframe 11: the agent says it drove from keyframe 10 to `truth` (its scan is taken
  // at `scan_at`, the truth unless given).
  Keyframe Revisit(const Pose2& truth, const std::optional<Pose2>& scan_at = std::nullopt) {
    std::vector<Pose2> path = path_;
    path.push_back(truth);
    Keyframe k = Drive(path, "R1", 1).back();
    if (scan_at) k.scan = Drive({*scan_at}, "elsewhere", 9).front().scan;
    return k;
  }

  const testing::SyntheticWorld world_ = LoopWorld();
  std::vector<Pose2> path_;
  TrajectoryTable table_;
  Smoother smoother_;
  ReducedGraphOptions options_;
  KeyframeFolder folder_{options_};
};

TEST_F(KeyframeFoldTest, AKeyframeNearANodeFoldsWithTheMatchAsItsOffset) {
  // Back at x = 4.2, 0.2 m east of node 3 (x = 4.0), 5 degrees to the left.
  const std::optional<KeyframeFold> fold = Try(Revisit(Pose2(4.2, 2.0, 0.087)));
  ASSERT_TRUE(fold.has_value());
  EXPECT_EQ(fold->node, (PoseKey{TrajectoryId(0), 3}));
  // The offset is the match: the true one within a few centimetres.
  EXPECT_NEAR(fold->T_node_keyframe.x(), 0.2, 0.03);
  EXPECT_NEAR(fold->T_node_keyframe.y(), 0.0, 0.03);
  EXPECT_NEAR(fold->T_node_keyframe.theta(), 0.087, 0.01);
  // Its covariance: the matcher's with the floors (2 cm, 0.005 rad) added.
  EXPECT_GE(fold->covariance(0, 0), 0.02 * 0.02);
  EXPECT_GE(fold->covariance(2, 2), 0.005 * 0.005);
  EXPECT_EQ(folder_.stats().folded, 1);
  EXPECT_EQ(folder_.num_nodes(), 11u);
}

TEST_F(KeyframeFoldTest, AFoldOntoItsPredecessorKeepsTheAgentsPrecision) {
  // 0.2 m past node 10, its predecessor: the agent's constraint (odometry noise 5 mm, 0.002 rad)
  // enters no factor inside one node, so it is fused with the match. With the match alone the
  // offset had the floors' 2 cm and 0.005 rad, and a fresh path folding every other keyframe
  // lost its odometry's precision (ACES split in two, docs/ARCHITECTURE.md, aces26).
  const std::optional<AdmittedKeyframe> a = PastTheLastNode();
  ASSERT_TRUE(a.has_value());
  const std::optional<KeyframeFold> fold = Decide(&folder_, *a);
  ASSERT_TRUE(fold.has_value());
  EXPECT_EQ(fold->node, (PoseKey{TrajectoryId(0), 10}));
  EXPECT_NEAR(fold->T_node_keyframe.x(), 0.2, 0.03);
  EXPECT_NEAR(fold->T_node_keyframe.y(), 0.0, 0.03);
  EXPECT_NEAR(fold->T_node_keyframe.theta(), 0.0, 0.01);
  // The agent's own covariance (the prediction's: the node is the predecessor's keyframe), not
  // the match's with the floors.
  for (int i = 0; i < 3; ++i) {
    EXPECT_NEAR(fold->covariance(i, i), a->T_previous_this_covariance(i, i),
                1e-9 * a->T_previous_this_covariance(i, i))
        << i;
    EXPECT_GT(fold->covariance(i, i), 0.0) << i;
  }
  EXPECT_LT(fold->covariance(0, 0), 0.02 * 0.02);
  EXPECT_LT(fold->covariance(2, 2), 0.005 * 0.005);
}

TEST_F(KeyframeFoldTest, AKeyframeFartherThanTheRadiusFromEveryNodeIsANode) {
  // 1.5 m past the last node.
  EXPECT_FALSE(Try(Revisit(Pose2(9.0, 2.0, 0.0))).has_value());
  EXPECT_EQ(folder_.stats().no_candidate, 1);
}

TEST_F(KeyframeFoldTest, AKeyframeTurnedMoreThanTheAngleIsANode) {
  // On node 3's place, turned by 60 degrees (the angle is 30).
  EXPECT_FALSE(Try(Revisit(Pose2(4.0, 2.0, kPiOver3))).has_value());
  EXPECT_EQ(folder_.stats().no_candidate, 1);
}

TEST_F(KeyframeFoldTest, AKeyframeOfAnotherFrameNeverFoldsOntoItsNodes) {
  // R2, unanchored, starts at the identity of its own frame, which puts its keyframe 1 at
  // (1.7, 0) there; R1's node 3 is at (1.5, 0) in R1's frame, but the frames differ.
  const std::vector<Keyframe> r2 = Drive({Pose2(2.5, 2.0, 0.0), Pose2(4.2, 2.0, 0.0)}, "R2", 2);
  ASSERT_TRUE(AddNode(r2[0]));
  std::vector<AdmittedKeyframe> admitted;
  ASSERT_TRUE(table_.Offer(r2[1], &admitted).ok());
  ASSERT_EQ(admitted.size(), 1u);
  const AdmittedKeyframe& a = admitted.front();
  // R2's own node 0 is 1.7 m away: no candidate, though R1's node 3 is 0.2 m away in numbers.
  EXPECT_FALSE(folder_
                   .Decide(a.key, *a.previous, a.T_previous_this, a.T_previous_this_covariance,
                           table_, &smoother_)
                   .has_value());
  EXPECT_EQ(folder_.stats().no_candidate, 1);
}

TEST_F(KeyframeFoldTest, AKeyframeWhoseScanDoesNotMatchTheNodeIsANode) {
  // Odometry puts it at x = 4.2, but its scan was taken in the north corridor.
  EXPECT_FALSE(Try(Revisit(Pose2(4.2, 2.0, 0.0), Pose2(12.0, 12.0, 0.0))).has_value());
  EXPECT_EQ(folder_.stats().weak_match + folder_.stats().gate_rejected, 1);
  EXPECT_EQ(folder_.stats().folded, 0);
}

TEST_F(KeyframeFoldTest, AMatchLessLocalisedThanTheBarsFoldsNothing) {
  // The place that folds in the first test, with bars below its match's own spread: the
  // keyframe becomes a node (on Intel's corridors such matches slid up to 1.7 m along them).
  ReducedGraphOptions strict;
  strict.max_sigma_m = 1e-4;
  folder_ = KeyframeFolder(strict);
  AddPathNodes(&folder_);
  EXPECT_FALSE(Try(Revisit(Pose2(4.2, 2.0, 0.087))).has_value());
  EXPECT_EQ(folder_.stats().degenerate, 1) << folder_.StatsLine();
  EXPECT_EQ(folder_.stats().gate_rejected + folder_.stats().weak_match, 0);
}

// The work counters (the status's "fold work"): a node's reference is built once and then
// served from the cache; the prediction is solved through R unless the predecessor is the
// node's keyframe or folded onto the node.
TEST_F(KeyframeFoldTest, WorkCountsCandidatesReferencesBuiltAndSolvedPredictions) {
  const std::vector<Keyframe> keyframes = TwiceOntoNodeThree();
  const std::optional<KeyframeFold> first = Try(keyframes[11]);
  ASSERT_TRUE(first.has_value());
  ASSERT_EQ(first->node, (PoseKey{TrajectoryId(0), 3}));
  const KeyframeFoldWork& work = folder_.work();
  // Nodes 2-5 (x = 3.5 ... 5.0) lie within 1 m of x = 4.2 and 30 degrees.
  EXPECT_EQ(work.candidates, 4);
  EXPECT_GE(work.near_nodes, work.candidates);
  EXPECT_EQ(work.matches, 1);
  EXPECT_EQ(work.reference_builds, 1);
  EXPECT_EQ(work.reference_hits, 0);
  EXPECT_EQ(work.solved_predictions, 1);  // node 3 from node 10, through R
  EXPECT_EQ(work.index_refreshes, 1);
  EXPECT_EQ(work.indexed_nodes, 11);
  // Keyframe 11 becomes an alias of node 3, as MappingServer makes it.
  const PoseKey key11{TrajectoryId(0), 11};
  ASSERT_TRUE(
      smoother_.AddAlias(key11, first->node, first->T_node_keyframe, first->covariance).ok());
  const std::optional<KeyframeFold> second = Try(keyframes[12]);
  ASSERT_TRUE(second.has_value());
  EXPECT_EQ(second->node, first->node);
  EXPECT_EQ(work.matches, 2);
  EXPECT_EQ(work.reference_builds, 1);
  EXPECT_EQ(work.reference_hits, 1);
  EXPECT_EQ(work.reference_rebuilds, 0);
  EXPECT_EQ(work.solved_predictions, 1);  // the predecessor's own offset: no solve
  EXPECT_EQ(folder_.stats().folded, 2);
  EXPECT_NE(work.Summary().find("reference_builds 1 reference_rebuilds 0 reference_hits 1"),
            std::string::npos)
      << work.Summary();
}

// Among many robots the shared cache has evicted a robot's node by its next keyframe (100 x 180
// seed 2: 17,918 references built for 20,423 matches with 32 kept); each trajectory keeps the
// reference it last matched against, so the robot's next fold onto that node builds nothing.
TEST_F(KeyframeFoldTest, ATrajectorysNextFoldOntoItsLastNodeReusesItsReference) {
  ReducedGraphOptions one_kept;
  one_kept.reference_cache = 1;
  folder_ = KeyframeFolder(one_kept);
  AddPathNodes(&folder_);
  const std::vector<Keyframe> r1 = TwiceOntoNodeThree();
  const std::optional<KeyframeFold> first = Try(r1[11]);
  ASSERT_TRUE(first.has_value());
  ASSERT_EQ(first->node, (PoseKey{TrajectoryId(0), 3}));
  ASSERT_TRUE(
      smoother_
          .AddAlias({TrajectoryId(0), 11}, first->node, first->T_node_keyframe, first->covariance)
          .ok());
  // R2 (its own frame) folds onto its own node in between: the one cached reference is now its.
  const std::vector<Keyframe> r2 = Drive({Pose2(2.5, 2.0, 0.0), Pose2(2.7, 2.0, 0.0)}, "R2", 2);
  ASSERT_TRUE(AddNode(r2[0]));
  const std::optional<KeyframeFold> other = Try(r2[1]);
  ASSERT_TRUE(other.has_value());
  EXPECT_EQ(other->node.trajectory, TrajectoryId(1));
  const KeyframeFoldWork& work = folder_.work();
  EXPECT_EQ(work.reference_builds, 2);
  const std::optional<KeyframeFold> second = Try(r1[12]);
  ASSERT_TRUE(second.has_value());
  EXPECT_EQ(second->node, first->node);
  EXPECT_EQ(work.matches, 3);
  EXPECT_EQ(work.reference_builds, 2);  // before: 3, node 3's evicted reference built again
  EXPECT_EQ(work.reference_rebuilds, 0);
  EXPECT_EQ(work.reference_hits, 1);
  EXPECT_EQ(work.reference_own_hits, 1);
}

// The verifying match searches three sigmas of its prediction, at least 0.1 m and 0.05 rad
// (the loop closures' 0.4 m and 0.2 rad before, cost28): a keyframe 0.2 m past its
// predecessor, the node, is predicted within millimetres by the agent's constraint, so the
// floors hold, and the match finds the same offset as in the wider window on a fraction of
// the lattice.
TEST_F(KeyframeFoldTest, AFoldsMatchSearchesThreeSigmasOfItsPredictionAboveTheFloors) {
  ReducedGraphOptions lattice;  // the lattice search for this chained fold too
  lattice.refine_chained_from_guess = false;
  ReducedGraphOptions wide = lattice;
  wide.min_window_m = 0.4;
  wide.min_window_rad = 0.2;
  folder_ = KeyframeFolder(lattice);
  KeyframeFolder wide_folder(wide);
  AddPathNodes(&folder_);
  AddPathNodes(&wide_folder);
  const std::optional<AdmittedKeyframe> a = PastTheLastNode();
  ASSERT_TRUE(a.has_value());
  const std::optional<KeyframeFold> fold = Decide(&folder_, *a);
  const std::optional<KeyframeFold> wide_fold = Decide(&wide_folder, *a);
  ASSERT_TRUE(fold.has_value());
  ASSERT_TRUE(wide_fold.has_value());
  EXPECT_EQ(fold->node, (PoseKey{TrajectoryId(0), 10}));
  EXPECT_NEAR(fold->T_node_keyframe.x(), 0.2, 0.03);
  EXPECT_NEAR(fold->T_node_keyframe.y(), 0.0, 0.03);
  // The same offset to the bit, the same covariance.
  EXPECT_EQ(fold->node, wide_fold->node);
  EXPECT_EQ(fold->T_node_keyframe.vector(), wide_fold->T_node_keyframe.vector());
  EXPECT_EQ(fold->covariance, wide_fold->covariance);
  const KeyframeFoldWork& work = folder_.work();
  EXPECT_EQ(work.window_mm, 100);
  EXPECT_EQ(work.window_mrad, 50);
  EXPECT_EQ(wide_folder.work().window_mm, 400);
  EXPECT_EQ(wide_folder.work().window_mrad, 200);
  // Lattice scores: 217 against 3006.
  EXPECT_LT(work.lattice_scores, wide_folder.work().lattice_scores / 10);
}

// A chained fold (here onto its predecessor, the node) is refined from its prediction without
// the lattice search, and lands where the lattice search's match lands.
TEST_F(KeyframeFoldTest, AChainedFoldIsRefinedFromItsPredictionWithoutTheLattice) {
  ReducedGraphOptions lattice;
  lattice.refine_chained_from_guess = false;
  KeyframeFolder lattice_folder(lattice);
  AddPathNodes(&lattice_folder);
  const std::optional<AdmittedKeyframe> a = PastTheLastNode();
  ASSERT_TRUE(a.has_value());
  const std::optional<KeyframeFold> fold = Decide(&folder_, *a);
  const std::optional<KeyframeFold> searched = Decide(&lattice_folder, *a);
  ASSERT_TRUE(fold.has_value());
  ASSERT_TRUE(searched.has_value());
  EXPECT_EQ(folder_.work().guess_refinements, 1);
  EXPECT_EQ(folder_.work().guess_fallbacks, 0);
  EXPECT_EQ(folder_.work().lattice_scores, 0);
  EXPECT_GT(lattice_folder.work().lattice_scores, 0);
  EXPECT_EQ(fold->node, searched->node);
  EXPECT_NEAR(fold->T_node_keyframe.x(), 0.2, 0.03);
  // The same optimum (measured 2e-9 m and 1.3e-9 rad apart: the refinement's stop).
  EXPECT_NEAR(fold->T_node_keyframe.x(), searched->T_node_keyframe.x(), 1e-6);
  EXPECT_NEAR(fold->T_node_keyframe.y(), searched->T_node_keyframe.y(), 1e-6);
  EXPECT_NEAR(fold->T_node_keyframe.theta(), searched->T_node_keyframe.theta(), 1e-6);
}

// A revisit predicted through R (not chained) is searched on the lattice as before.
TEST_F(KeyframeFoldTest, AFoldPredictedThroughTheSolverIsSearchedOnTheLattice) {
  ASSERT_TRUE(Try(Revisit(Pose2(4.2, 2.0, 0.087))).has_value());
  EXPECT_EQ(folder_.work().guess_refinements, 0);
  EXPECT_EQ(folder_.work().guess_fallbacks, 0);
  EXPECT_GT(folder_.work().lattice_scores, 0);
}

TEST(ReducedGraphOptionsTest, BadRadiusAndAngleAreRefusedByName) {
  ReducedGraphOptions options;
  EXPECT_TRUE(options.Validate().ok());
  options.radius_m = 0.0;
  EXPECT_NE(options.Validate().message().find("--reduced-graph-radius-m"), std::string::npos);
  options = ReducedGraphOptions{};
  options.angle_deg = 200.0;
  EXPECT_NE(options.Validate().message().find("--reduced-graph-angle-deg"), std::string::npos);
}

}  // namespace
}  // namespace anchormap
