// The global search of unjoined trajectories (GlobalSearchPlanner): its budget and the search
// guided by a kept hypothesis, through ScanEncounters.
#include "server/global_search_planner.h"

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

// The guided global search picks the group's trajectory too: R3 holds a map-verified hypothesis
// against {R1, R2} (R2[10]-R3[35]); at keyframes where it puts R3 nearest a submap of R2, both
// keyframes' searches go to R2, though the pair searched least (R1, then by id) would take the
// first one. Without the hypothesis the two keyframes search R1 and R2 in turn.
// R1 and R2 joined by a direct encounter at their first keyframes, R3 not (testing::ThreeLaps).
class GuidedSearchTest : public ::testing::Test, protected testing::ThreeLaps {
 protected:
  void SetUp() override { ASSERT_TRUE(Drive(/*r1_sees_r2=*/true)); }
};

TEST_F(GuidedSearchTest, AGuidedSearchTakesTheGroupsTrajectoryNearestTheKeyframe) {
  const ScanEncounterOptions defaults;
  // Submap centres (keyframes 5, 15, ...) of R1 and R2, and R3's keyframes searched globally
  // whose nearest centre is R2's, within the guide's reach and 1 m nearer than any of R1's.
  const auto nearest_m = [&](size_t r, size_t j) {
    double nearest = 1e9;
    for (size_t c = 5; c + 5 < paths_[r].size(); c += 10) {
      nearest = std::min(nearest, (paths_[r][c].translation() - paths_[2][j].translation()).norm());
    }
    return nearest;
  };
  std::vector<int32_t> near_r2;
  for (size_t j = 40; j < paths_[2].size() && near_r2.size() < 2; j += 5) {
    if (nearest_m(1, j) < defaults.guide_max_distance_m &&
        nearest_m(1, j) + 1.0 < nearest_m(0, j)) {
      near_r2.push_back(static_cast<int32_t>(j));
    }
  }
  ASSERT_EQ(near_r2.size(), 2u);
  const auto searches = [&](bool hypothesis) {
    ScanEncounterOptions options;
    options.first_join_hold_s = 1e6;  // the hypothesis stays kept
    options.near_catch_up_every = 0;
    options.max_global_per_keyframe = 1;  // one search per keyframe: the target shows
    ScanEncounters source(options);
    const GraphView graph{server_->table(), server_->smoother(), &server_->mutable_smoother()};
    EncounterSourceOutput out;
    source.Poll(100'000'000, graph, &out);
    if (hypothesis) source.OfferCandidate(Candidate(1, 10, 35), graph, &out);
    for (const int32_t j : near_r2) {
      source.OnKeyframeAdded({TrajectoryId(2), j}, graph, &out);
      source.Poll(100'000'000, graph, &out);
    }
    return std::make_pair(source.global_searches().PairSearches(TrajectoryId(2), TrajectoryId(0)),
                          source.global_searches().PairSearches(TrajectoryId(2), TrajectoryId(1)));
  };
  std::printf(
      "R3 keyframes %d and %d nearest R2's submaps (%.1f and %.1f m; R1's %.1f and %.1f m)\n",
      near_r2[0], near_r2[1], nearest_m(1, static_cast<size_t>(near_r2[0])),
      nearest_m(1, static_cast<size_t>(near_r2[1])), nearest_m(0, static_cast<size_t>(near_r2[0])),
      nearest_m(0, static_cast<size_t>(near_r2[1])));
  EXPECT_EQ(searches(/*hypothesis=*/true), std::make_pair(int64_t{0}, int64_t{2}));
  EXPECT_EQ(searches(/*hypothesis=*/false), std::make_pair(int64_t{1}, int64_t{1}));
}

// Eight robots that never meet, keyframes 1 s apart: how many global searches they cost.
struct BudgetRun {
  int64_t searches = 0;
  int64_t fewest_by_one = 0;  // searches of the trajectory searched least
  int64_t most_by_one = 0;
  double data_s = 0.0;
};

BudgetRun RunBudget(const GlobalSearchBudgetOptions& budget) {
  constexpr int kRobots = 8;
  constexpr int kKeyframes = 40;
  MappingServerOptions options;
  options.loop_closures = false;
  options.scan_encounters = false;
  MappingServer server(options);
  ScanEncounterOptions scan_options;
  scan_options.global_budget = budget;
  auto scan = std::make_unique<ScanEncounters>(scan_options);
  ScanEncounters* source = scan.get();
  server.AddEncounterSource(std::move(scan));
  for (int32_t seq = 0; seq < kKeyframes; ++seq) {
    for (int r = 0; r < kRobots; ++r) {
      EXPECT_TRUE(
          server.OnKeyframe(testing::StraightKeyframe("R" + std::to_string(r), r + 1, seq, 40))
              .ok());
    }
  }
  server.Flush();
  BudgetRun run;
  const GlobalSearchQueue& queue = source->global_searches();
  run.searches = queue.searches();
  run.fewest_by_one = queue.Searched(TrajectoryId(0));
  for (int r = 0; r < kRobots; ++r) {
    run.fewest_by_one = std::min(run.fewest_by_one, queue.Searched(TrajectoryId(r)));
    run.most_by_one = std::max(run.most_by_one, queue.Searched(TrajectoryId(r)));
  }
  run.data_s = kKeyframes - 1;
  return run;
}

TEST(ScanEncountersTest, GlobalSearchesStayWithinTheTeamBudget) {
  GlobalSearchBudgetOptions unbounded;
  unbounded.searches_per_s = 1e6;
  unbounded.burst = 1e6;
  const BudgetRun free_run = RunBudget(unbounded);
  GlobalSearchBudgetOptions budget;
  budget.searches_per_s = 1.0;
  budget.burst = 4.0;
  const BudgetRun bounded = RunBudget(budget);
  std::printf("global searches: unbounded %lld, budget %lld (%lld..%lld per robot)\n",
              static_cast<long long>(free_run.searches), static_cast<long long>(bounded.searches),
              static_cast<long long>(bounded.fewest_by_one),
              static_cast<long long>(bounded.most_by_one));
  // Per keyframe at most 2 groups x 2 submaps, whatever the team: 8 robots, every 5th of 40
  // keyframes, and no submap before keyframe 10.
  EXPECT_LE(free_run.searches, 8 * 8 * 4);
  EXPECT_GT(free_run.searches, 3 * bounded.searches);
  // The bucket's bound: the burst plus the rate over the data.
  EXPECT_LE(static_cast<double>(bounded.searches),
            budget.burst + budget.searches_per_s * bounded.data_s);
  EXPECT_GE(static_cast<double>(bounded.searches),
            budget.searches_per_s * bounded.data_s - 2 * budget.burst);
  // Fair: every robot is served, none more than one keyframe's searches ahead.
  EXPECT_GE(bounded.fewest_by_one, 1);
  EXPECT_LE(bounded.most_by_one - bounded.fewest_by_one, 4);
}

}  // namespace
}  // namespace anchormap
