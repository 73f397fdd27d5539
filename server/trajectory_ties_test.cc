#include "server/trajectory_ties.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <random>
#include <vector>

namespace anchormap {
namespace {

const TrajectoryId kA(0), kB(1), kC(2);

// Every keyframe 1 m further than the one before, in every trajectory.
double OneMetreEach(PoseKey key) { return key.index; }

// A team of trajectories whose keyframes are random uneven steps apart, and the brute force of
// its drives: along each trajectory, plus every tie, closed by Floyd-Warshall.
class BruteForceTeam {
 public:
  BruteForceTeam(int trajectories, int keyframes, std::mt19937* random)
      : keyframes_(keyframes),
        n_(static_cast<size_t>(trajectories * keyframes)),
        step_(n_),
        direct_(n_ * n_, std::numeric_limits<double>::infinity()) {
    for (double& s : step_) s = std::uniform_real_distribution<double>(0.1, 2.0)(*random);
    for (int t = 0; t < trajectories; ++t) {
      for (int i = 0; i < keyframes; ++i) {
        for (int j = 0; j < keyframes; ++j) {
          const PoseKey a{TrajectoryId(t), i}, b{TrajectoryId(t), j};
          direct_[Node(a) * n_ + Node(b)] = std::abs(Driven(a) - Driven(b));
        }
      }
    }
  }
  // The path a keyframe's trajectory drove to it from its first keyframe.
  double Driven(PoseKey key) const {
    double path = 0.0;
    for (int i = 1; i <= key.index; ++i) path += step_[Node({key.trajectory, i})];
    return path;
  }
  // A tie as TrajectoryTies::Add takes it (one within a trajectory is ignored).
  void Tie(PoseKey a, PoseKey b) {
    if (a.trajectory != b.trajectory)
      direct_[Node(a) * n_ + Node(b)] = direct_[Node(b) * n_ + Node(a)] = 0.0;
  }
  // Every pair's shortest drive through the ties so far; Drive reads it.
  std::vector<double> Shortest() const {
    std::vector<double> d = direct_;
    for (size_t k = 0; k < n_; ++k) {
      for (size_t i = 0; i < n_; ++i) {
        for (size_t j = 0; j < n_; ++j)
          d[i * n_ + j] = std::min(d[i * n_ + j], d[i * n_ + k] + d[k * n_ + j]);
      }
    }
    return d;
  }
  double Drive(const std::vector<double>& shortest, PoseKey from, PoseKey to) const {
    return shortest[Node(from) * n_ + Node(to)];
  }

 private:
  size_t Node(PoseKey key) const {
    return static_cast<size_t>(key.trajectory.value() * keyframes_ + key.index);
  }

  int keyframes_;
  size_t n_;
  std::vector<double> step_;
  std::vector<double> direct_;  // along each trajectory, and 0 across a tie
};

TEST(TrajectoryTiesTest, UntiedTrajectoriesHaveNoDrive) {
  TrajectoryTies ties;
  EXPECT_FALSE(ties.ShortestDrive({kA, 3}, {kB, 4}, OneMetreEach));
  ties.Add({kA, 0}, {kA, 9});  // a loop closure ties nothing
  EXPECT_EQ(ties.size(), 0);
  EXPECT_FALSE(ties.ShortestDrive({kA, 3}, {kB, 4}, OneMetreEach));
}

TEST(TrajectoryTiesTest, TheNearestTieOfThePairCounts) {
  TrajectoryTies ties;
  ties.Add({kA, 10}, {kB, 50});
  ties.Add({kB, 20}, {kA, 40});  // either way round
  // A[42] to B[25]: 2 m to A[40], then 5 m from B[20]; through the other tie 32 + 25.
  ASSERT_TRUE(ties.ShortestDrive({kA, 42}, {kB, 25}, OneMetreEach));
  EXPECT_DOUBLE_EQ(*ties.ShortestDrive({kA, 42}, {kB, 25}, OneMetreEach), 7.0);
  EXPECT_DOUBLE_EQ(*ties.ShortestDrive({kB, 25}, {kA, 42}, OneMetreEach), 7.0);
  EXPECT_DOUBLE_EQ(*ties.ShortestDrive({kA, 10}, {kB, 50}, OneMetreEach), 0.0);
}

TEST(TrajectoryTiesTest, AChainThroughAThirdTrajectoryCounts) {
  TrajectoryTies ties;
  ties.Add({kA, 5}, {kC, 100});
  ties.Add({kC, 104}, {kB, 30});
  ties.Add({kA, 90}, {kB, 90});
  // A[8] to B[33]: 3 (A 8->5) + 4 (C 100->104) + 3 (B 30->33) = 10, not 82 + 57.
  EXPECT_DOUBLE_EQ(*ties.ShortestDrive({kA, 8}, {kB, 33}, OneMetreEach), 10.0);
  // Near the direct tie, the direct tie: 1 + 2.
  EXPECT_DOUBLE_EQ(*ties.ShortestDrive({kA, 89}, {kB, 92}, OneMetreEach), 3.0);
}

TEST(TrajectoryTiesTest, ALimitAnswersOnlyDrivesWithinIt) {
  TrajectoryTies ties;
  ties.Add({kA, 5}, {kC, 100});
  ties.Add({kC, 104}, {kB, 30});
  ties.Add({kA, 90}, {kB, 90});
  // A[8] to B[33] is 10 m through C (above): within a limit of 10, not of 9.99.
  EXPECT_DOUBLE_EQ(*ties.ShortestDrive({kA, 8}, {kB, 33}, OneMetreEach, 10.0), 10.0);
  EXPECT_FALSE(ties.ShortestDrive({kA, 8}, {kB, 33}, OneMetreEach, 9.99));
  EXPECT_DOUBLE_EQ(*ties.ShortestDrive({kA, 89}, {kB, 92}, OneMetreEach, 4.0), 3.0);
  EXPECT_FALSE(ties.ShortestDrive({kA, 3}, {kA, 9}, OneMetreEach, 5.0));  // 6 m along A
}

// The search keeps its queue and settled set between calls: a long search (a ladder of 300
// ties between two trajectories, so the settled set grows several times) leaves nothing
// behind that changes the next answers (no cap: the far search settles all 600).
TEST(TrajectoryTiesTest, RepeatedSearchesGiveTheSameDrives) {
  TrajectoryTies ties(/*max_settled=*/0);
  for (int32_t i = 0; i < 300; ++i) ties.Add({kA, 2 * i}, {kB, 2 * i + 1});
  ties.Add({kB, 1000}, {kC, 0});
  // B[1000] to C[7]: tied at C[0], then 7 m along C.
  const auto far = [&] { return ties.ShortestDrive({kA, 0}, {kC, 7}, OneMetreEach); };
  const auto near = [&] { return ties.ShortestDrive({kA, 42}, {kB, 45}, OneMetreEach); };
  const auto bounded = [&] { return ties.ShortestDrive({kA, 3}, {kA, 9}, OneMetreEach, 5.0); };
  for (int round = 0; round < 3; ++round) {
    // A[0] to B[1]: tied; then up B to B[1000] (999 m), then 7 m along C.
    ASSERT_TRUE(far());
    EXPECT_DOUBLE_EQ(*far(), 1006.0);
    // A[42] to B[45]: A[42]'s tie goes to B[43], then 2 m along B.
    ASSERT_TRUE(near());
    EXPECT_DOUBLE_EQ(*near(), 2.0);
    EXPECT_FALSE(bounded());
  }
}

TEST(TrajectoryTiesTest, ConnectedFollowsChainsOfTies) {
  TrajectoryTies ties;
  const TrajectoryId kD(3);
  EXPECT_TRUE(ties.Connected(kA, kA));
  EXPECT_FALSE(ties.Connected(kA, kB));
  ties.Add({kC, 1}, {kD, 2});
  ties.Add({kA, 0}, {kA, 9});  // a loop closure connects nothing
  EXPECT_FALSE(ties.Connected(kA, kD));
  ties.Add({kB, 7}, {kA, 3});
  EXPECT_TRUE(ties.Connected(kA, kB));
  EXPECT_FALSE(ties.Connected(kB, kC));
  ties.Add({kD, 5}, {kB, 8});  // joins {A, B} and {C, D}
  EXPECT_TRUE(ties.Connected(kA, kC));
  EXPECT_TRUE(ties.Connected(kD, kA));
  // A bounded drive that says nothing is either beyond the limit (connected) or none at all.
  EXPECT_FALSE(ties.ShortestDrive({kA, 3}, {kC, 50}, OneMetreEach, 5.0));
  EXPECT_DOUBLE_EQ(*ties.ShortestDrive({kA, 3}, {kC, 50}, OneMetreEach), 53.0);
  ties.Clear();
  EXPECT_FALSE(ties.Connected(kA, kB));
}

TEST(TrajectoryTiesTest, TiesAddedInAnyIndexOrderAreSearchedByIndex) {
  TrajectoryTies ties;
  // A's tied keyframes arrive out of index order, one of them tied twice.
  ties.Add({kA, 60}, {kB, 10});
  ties.Add({kA, 20}, {kC, 70});
  ties.Add({kA, 40}, {kB, 90});
  ties.Add({kA, 20}, {kB, 45});
  // B[47] to A[22]: 2 m back along B to B[45], its tie to A[20], then 2 m: 4.
  EXPECT_DOUBLE_EQ(*ties.ShortestDrive({kB, 47}, {kA, 22}, OneMetreEach), 4.0);
  // C[75] to B[12]: C[70] (5), A[20] -> A[60] (40), B[10] (2) = 47; or A[20]'s other
  // partner B[45] (33 back along B): 5 + 33 = 38.
  EXPECT_DOUBLE_EQ(*ties.ShortestDrive({kC, 75}, {kB, 12}, OneMetreEach), 38.0);
  // A[50] lies between A's tied 40 and 60: B[88] is 10 + 2 away, B[12] 10 + 2.
  EXPECT_DOUBLE_EQ(*ties.ShortestDrive({kA, 50}, {kB, 88}, OneMetreEach), 12.0);
  EXPECT_DOUBLE_EQ(*ties.ShortestDrive({kA, 50}, {kB, 12}, OneMetreEach), 12.0);
  EXPECT_EQ(ties.size(), 4);
}

// Random ties between four trajectories of 60 keyframes with uneven steps, against the
// brute force (Floyd-Warshall over every keyframe, its drives along each trajectory and its
// ties): the search's drives, bounded and not, and DriveBelow's answers, after every tie
// added (ties to keyframes between, above and below earlier ones, and repeated).
TEST(TrajectoryTiesTest, DrivesEqualTheBruteForceAsTiesArrive) {
  constexpr int kTrajectories = 4, kKeyframes = 60;
  std::mt19937 random(7);
  BruteForceTeam team(kTrajectories, kKeyframes, &random);
  const auto driven = [&team](PoseKey key) { return team.Driven(key); };
  std::uniform_int_distribution<int> trajectory(0, kTrajectories - 1), index(0, kKeyframes - 1);
  TrajectoryTies ties;
  int checked = 0, below = 0;
  for (int tie = 0; tie < 40; ++tie) {
    const PoseKey a{TrajectoryId(trajectory(random)), index(random)};
    const PoseKey b{TrajectoryId(trajectory(random)), index(random)};
    ties.Add(a, b);
    team.Tie(a, b);
    const std::vector<double> shortest = team.Shortest();
    for (int query = 0; query < 30; ++query) {
      const PoseKey from{TrajectoryId(trajectory(random)), index(random)};
      const PoseKey to{TrajectoryId(trajectory(random)), index(random)};
      const double truth = team.Drive(shortest, from, to);
      const std::optional<double> drive = ties.ShortestDrive(from, to, driven);
      ASSERT_EQ(drive.has_value(), std::isfinite(truth));
      if (drive) {
        EXPECT_NEAR(*drive, truth, 1e-9);
      }
      for (const double limit : {2.0, 5.0, 20.0}) {
        const std::optional<double> bounded = ties.ShortestDrive(from, to, driven, limit);
        EXPECT_EQ(bounded.has_value(), truth <= limit + 1e-9 && std::isfinite(truth));
        const bool is_below = ties.DriveBelow(from, to, driven, limit);
        EXPECT_EQ(is_below, drive && *drive < limit);
        below += is_below ? 1 : 0;
        ++checked;
      }
    }
  }
  // Both answers occur (the test asks something).
  EXPECT_GT(below, checked / 10);
  EXPECT_LT(below, checked - checked / 10);
}

// The same brute force against searches capped at a few tied keyframes: a capped answer's
// range holds the true drive, an answer the cap did not stop is exact, and DriveBelow says
// "below" when the cap stopped it.
TEST(TrajectoryTiesTest, CappedSearchesBoundTheBruteForce) {
  constexpr int kTrajectories = 4, kKeyframes = 40;
  constexpr double kInf = std::numeric_limits<double>::infinity();
  std::mt19937 random(11);
  BruteForceTeam team(kTrajectories, kKeyframes, &random);
  const auto driven = [&team](PoseKey key) { return team.Driven(key); };
  std::uniform_int_distribution<int> trajectory(0, kTrajectories - 1), index(0, kKeyframes - 1);
  TrajectoryTies capped(/*max_settled=*/6), uncapped(/*max_settled=*/0);
  for (int tie = 0; tie < 60; ++tie) {
    const PoseKey a{TrajectoryId(trajectory(random)), index(random)};
    const PoseKey b{TrajectoryId(trajectory(random)), index(random)};
    capped.Add(a, b);
    uncapped.Add(a, b);
    team.Tie(a, b);
  }
  const std::vector<double> shortest = team.Shortest();
  int exact = 0, stopped = 0;
  for (int query = 0; query < 2000; ++query) {
    const PoseKey from{TrajectoryId(trajectory(random)), index(random)};
    const PoseKey to{TrajectoryId(trajectory(random)), index(random)};
    const double truth = team.Drive(shortest, from, to);
    for (const double limit : {3.0, 10.0, kInf}) {
      const TrajectoryTies::DriveRange range = capped.Drive(from, to, driven, limit);
      const TrajectoryTies::DriveRange whole = uncapped.Drive(from, to, driven, limit);
      EXPECT_FALSE(whole.capped);
      EXPECT_LE(range.at_least, truth + 1e-9);
      EXPECT_GE(range.at_most, truth - 1e-9);
      if (truth <= limit) {
        EXPECT_NEAR(whole.at_most, truth, 1e-9);
        EXPECT_EQ(whole.at_least, whole.at_most);
      } else {
        EXPECT_GE(whole.at_least, limit);
      }
      if (range.capped) {
        EXPECT_LT(range.at_least, range.at_most);
        EXPECT_TRUE(capped.DriveBelow(from, to, driven, limit));
        EXPECT_FALSE(capped.ShortestDrive(from, to, driven, limit));
        ++stopped;
      } else if (range.at_least == range.at_most) {  // exact
        if (std::isfinite(truth)) {
          EXPECT_NEAR(range.at_most, truth, 1e-9);
        } else {
          EXPECT_EQ(range.at_most, kInf);
        }
        EXPECT_EQ(capped.DriveBelow(from, to, driven, limit), truth < limit);
        ++exact;
      } else {  // beyond the limit
        EXPECT_GE(range.at_least, limit);
        EXPECT_FALSE(capped.DriveBelow(from, to, driven, limit));
        ++exact;
      }
    }
  }
  // Both kinds of answer occur (the cap binds, and not always).
  EXPECT_GT(stopped, 300);
  EXPECT_GT(exact, 300);
  EXPECT_GT(capped.search_stats().capped, 0);
  EXPECT_EQ(uncapped.search_stats().capped, 0);
}

// A place that many passes tie together: the tied keyframes within a few metres of drive
// outnumber the cap, and the saturation question is answered "below" after the cap's
// keyframes instead of a search of all of them.
TEST(TrajectoryTiesTest, ADenselyTiedPlaceIsBelowAtTheCap) {
  TrajectoryTies ties(/*max_settled=*/16);
  // Trajectory 0..39 each pass keyframes 0..9 (1 m apart) of one place, each pass's keyframe k
  // tied to the next pass's keyframe k; trajectory 40 is tied only at the far end of pass 39.
  for (int32_t pass = 0; pass + 1 < 40; ++pass) {
    for (int32_t k = 0; k < 10; ++k) ties.Add({TrajectoryId(pass), k}, {TrajectoryId(pass + 1), k});
  }
  ties.Add({TrajectoryId(39), 9}, {TrajectoryId(40), 0});
  const auto before = ties.search_stats();
  // Pass 0's keyframe 0 to trajectory 40's keyframe 0: 9 m (up pass 39); under 4 m it is not.
  EXPECT_TRUE(ties.DriveBelow({TrajectoryId(0), 0}, {TrajectoryId(40), 0}, OneMetreEach, 4.0));
  EXPECT_EQ(ties.search_stats().capped - before.capped, 1);
  EXPECT_LE(ties.search_stats().settled - before.settled, 16);
  TrajectoryTies uncapped(/*max_settled=*/0);
  for (int32_t pass = 0; pass + 1 < 40; ++pass) {
    for (int32_t k = 0; k < 10; ++k) {
      uncapped.Add({TrajectoryId(pass), k}, {TrajectoryId(pass + 1), k});
    }
  }
  uncapped.Add({TrajectoryId(39), 9}, {TrajectoryId(40), 0});
  EXPECT_FALSE(uncapped.DriveBelow({TrajectoryId(0), 0}, {TrajectoryId(40), 0}, OneMetreEach, 4.0));
  EXPECT_DOUBLE_EQ(
      *uncapped.ShortestDrive({TrajectoryId(0), 0}, {TrajectoryId(40), 0}, OneMetreEach), 9.0);
}

}  // namespace
}  // namespace anchormap
