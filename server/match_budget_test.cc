#include "server/match_budget.h"

#include <map>
#include <vector>

#include <gtest/gtest.h>

namespace anchormap {
namespace {

MatchBudgetOptions Budget(double per_s, double burst, double skip_priority_m = 0.5) {
  MatchBudgetOptions options;
  options.units_per_s = per_s;
  options.burst = burst;
  options.skip_priority_m = skip_priority_m;
  return options;
}

// Serves `requests`, each costing `cost` units; returns the keys served, in serving order.
std::vector<PoseKey> ServeAll(MatchBudget* budget, const std::vector<BudgetRequest>& requests,
                              double max_units, double cost) {
  std::vector<PoseKey> served;
  budget->Serve(requests, max_units, [&](PoseKey key) {
    served.push_back(key);
    return cost;
  });
  return served;
}

TEST(MatchBudgetTest, WhenTheTokensCoverEveryKeyframeAllAreServedInArrivalOrder) {
  MatchBudget budget(Budget(10.0, 30.0));
  budget.Advance(0);
  const std::vector<BudgetRequest> requests{
      {{TrajectoryId(2), 7}, 1.0}, {{TrajectoryId(0), 3}, 50.0}, {{TrajectoryId(1), 9}, 9.0}};
  // 3 keyframes of at most 10 units: 30 tokens cover them.
  const std::vector<PoseKey> served = ServeAll(&budget, requests, 10.0, 4.0);
  ASSERT_EQ(served.size(), 3u);
  EXPECT_EQ(served[0], requests[0].key);
  EXPECT_EQ(served[1], requests[1].key);
  EXPECT_EQ(served[2], requests[2].key);
  EXPECT_DOUBLE_EQ(budget.tokens(), 18.0);  // charged what they spent
  EXPECT_EQ(budget.skipped(), 0);
}

TEST(MatchBudgetTest, UnboundedServesAllAndChargesNothing) {
  MatchBudget budget(Budget(0.0, 0.0));
  budget.Advance(0);
  std::vector<BudgetRequest> requests;
  for (int i = 0; i < 100; ++i) requests.push_back({{TrajectoryId(i), 0}, 0.0});
  EXPECT_EQ(ServeAll(&budget, requests, 10.0, 10.0).size(), 100u);
  EXPECT_EQ(budget.spent(), 0.0);
}

TEST(MatchBudgetTest, TokensAccrueInDataTimeUpToTheBurst) {
  MatchBudget budget(Budget(4.0, 10.0));
  budget.Advance(5'000'000);
  budget.Spend(10.0);
  EXPECT_DOUBLE_EQ(budget.tokens(), 0.0);
  budget.Advance(5'500'000);  // 0.5 s: 2 units
  EXPECT_DOUBLE_EQ(budget.tokens(), 2.0);
  budget.Advance(4'000'000);  // time never goes back
  EXPECT_DOUBLE_EQ(budget.tokens(), 2.0);
  budget.Advance(100'000'000);  // a long gap saves at most the burst
  EXPECT_DOUBLE_EQ(budget.tokens(), 10.0);
}

TEST(MatchBudgetTest, ShortOfTokensTheLongestDriveSinceItsLastServedKeyframeGoesFirst) {
  MatchBudget budget(Budget(1.0, 5.0));
  budget.Advance(0);
  // Trajectory 1 was served at 40 m of drive, 2 at 10 m (3 never).
  ASSERT_EQ(
      ServeAll(&budget, {{{TrajectoryId(1), 10}, 40.0}, {{TrajectoryId(2), 4}, 10.0}}, 2.0, 1.0)
          .size(),
      2u);
  budget.Spend(budget.tokens() - 2.0);  // 2 units left: two keyframes of 1 unit, of 4
  const std::vector<BudgetRequest> requests{
      {{TrajectoryId(1), 20}, 45.0},  // 5 m since its last served keyframe
      {{TrajectoryId(2), 30}, 22.0},  // 12 m
      {{TrajectoryId(3), 2}, 8.0},    // 8 m since its start
      {{TrajectoryId(2), 29}, 21.5},  // 11.5 m, but 2's newer one takes its turn first
  };
  const std::vector<PoseKey> served = ServeAll(&budget, requests, 3.0, 1.0);
  ASSERT_EQ(served.size(), 2u);
  EXPECT_EQ(served[0], (PoseKey{TrajectoryId(2), 30}));
  EXPECT_EQ(served[1], (PoseKey{TrajectoryId(3), 2}));
  EXPECT_EQ(budget.skipped(), 2);
}

TEST(MatchBudgetTest, AServedKeyframeMayRunIntoDebtThatLaterTokensRepay) {
  MatchBudget budget(Budget(2.0, 3.0));
  budget.Advance(0);
  std::vector<BudgetRequest> requests;
  for (int i = 0; i < 4; ++i) requests.push_back({{TrajectoryId(i), 0}, 1.0 + i});
  // 3 tokens, 4 keyframes of up to 2 units, each spending 2: two served (3 -> 1 -> -1).
  EXPECT_EQ(ServeAll(&budget, requests, 2.0, 2.0).size(), 2u);
  EXPECT_DOUBLE_EQ(budget.tokens(), -1.0);
  budget.Advance(400'000);  // 0.8 units: still in debt, nothing served
  EXPECT_TRUE(ServeAll(&budget, {{{TrajectoryId(0), 1}, 2.0}}, 2.0, 2.0).empty());
  budget.Advance(1'000'000);  // 2 units in all: 1 left
  EXPECT_EQ(ServeAll(&budget, {{{TrajectoryId(0), 2}, 3.0}, {{TrajectoryId(1), 2}, 3.0}}, 2.0, 2.0)
                .size(),
            1u);
}

// 20 trajectories of which one drives 20 times slower than the others, the budget one
// keyframe per round: every trajectory is served, the slow one too, and the same input
// gives the same choices.
TEST(MatchBudgetTest, NoTrajectoryStarvesAndTheChoicesAreDeterministic) {
  const auto run = [] {
    MatchBudget budget(Budget(1.0, 1.0));
    std::map<int64_t, int> served_count;
    std::vector<PoseKey> order;
    for (int round = 0; round < 400; ++round) {
      budget.Advance(int64_t{1'000'000} * round);
      std::vector<BudgetRequest> requests;
      for (int t = 0; t < 20; ++t) {
        const double speed = t == 7 ? 0.05 : 1.0;  // metres per round
        requests.push_back({{TrajectoryId(t), round}, speed * round});
      }
      for (const PoseKey key : ServeAll(&budget, requests, 1.0, 1.0)) {
        ++served_count[key.trajectory.value()];
        order.push_back(key);
      }
    }
    return std::make_pair(served_count, order);
  };
  const auto [count, order] = run();
  EXPECT_EQ(order.size(), 400u);  // one per round
  ASSERT_EQ(count.size(), 20u);
  for (const auto& [trajectory, n] : count) {
    EXPECT_GE(n, trajectory == 7 ? 5 : 15) << "trajectory " << trajectory;
  }
  EXPECT_EQ(run().second, order);
}

TEST(MatchBudgetTest, OptionsAreValidated) {
  EXPECT_TRUE(Budget(0.0, 0.0).Validate("loop.budget").ok());
  EXPECT_TRUE(Budget(20.0, 60.0).Validate("loop.budget").ok());
  EXPECT_FALSE(Budget(-1.0, 60.0).Validate("loop.budget").ok());
  EXPECT_FALSE(Budget(1.0, -1.0).Validate("loop.budget").ok());
  EXPECT_FALSE(Budget(1.0, 1.0, -0.5).Validate("loop.budget").ok());
}

}  // namespace
}  // namespace anchormap
