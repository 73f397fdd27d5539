#include "server/global_search_queue.h"

#include <limits>

#include <gtest/gtest.h>

namespace anchormap {
namespace {

const TrajectoryId kA(0), kB(1), kC(2);

GlobalSearchBudgetOptions Budget(double per_s, double burst) {
  GlobalSearchBudgetOptions options;
  options.searches_per_s = per_s;
  options.burst = burst;
  return options;
}

TEST(GlobalSearchQueueTest, TokensAccrueInDataTimeUpToTheBurst) {
  GlobalSearchQueue queue(Budget(2.0, 5.0));
  queue.Advance(10'000'000);
  EXPECT_TRUE(queue.CanAfford(5));  // starts full
  EXPECT_FALSE(queue.CanAfford(6));
  queue.Enqueue({kA, 0});
  queue.Served({kA, 0}, 5);
  EXPECT_FALSE(queue.CanAfford(1));
  queue.Advance(10'400'000);  // 0.4 s: 0.8 token
  EXPECT_FALSE(queue.CanAfford(1));
  queue.Advance(10'600'000);  // 0.6 s: 1.2 tokens
  EXPECT_TRUE(queue.CanAfford(1));
  EXPECT_FALSE(queue.CanAfford(2));
  queue.Advance(9'000'000);  // time never goes back: nothing accrues, nothing is lost
  EXPECT_TRUE(queue.CanAfford(1));
  queue.Advance(100'000'000);  // a long gap saves at most the burst
  EXPECT_TRUE(queue.CanAfford(5));
  EXPECT_FALSE(queue.CanAfford(6));
  EXPECT_EQ(queue.searches(), 5);
}

TEST(GlobalSearchQueueTest, TheTrajectorySearchedLeastIsServedFirst) {
  GlobalSearchQueue queue(Budget(1.0, 10.0));
  queue.Advance(0);
  queue.Enqueue({kB, 5});
  queue.Enqueue({kA, 5});
  ASSERT_TRUE(queue.Next().has_value());
  EXPECT_EQ(queue.Next()->trajectory, kA);  // a tie: the smaller id
  queue.Served({kA, 5}, 4);
  EXPECT_EQ(queue.Searched(kA), 4);
  queue.Enqueue({kA, 10});
  queue.Enqueue({kC, 5});
  EXPECT_EQ(queue.Next()->trajectory, kB);  // 0 searches, before A's 4
  queue.Served({kB, 5}, 2);
  EXPECT_EQ(queue.Next()->trajectory, kC);
  queue.Served({kC, 5}, 2);
  EXPECT_EQ(queue.Next()->trajectory, kA);
  EXPECT_EQ(queue.waiting(), 1u);
}

TEST(GlobalSearchQueueTest, ANewerKeyframeReplacesTheWaitingOne) {
  GlobalSearchQueue queue(Budget(1.0, 10.0));
  queue.Enqueue({kA, 5});
  queue.Enqueue({kA, 5});  // the same keyframe again: nothing replaced
  EXPECT_EQ(queue.dropped(), 0);
  queue.Enqueue({kA, 10});
  EXPECT_EQ(queue.waiting(), 1u);
  EXPECT_EQ(queue.dropped(), 1);
  EXPECT_EQ(queue.Next()->index, 10);
  queue.Served({kA, 10}, 0);  // no target left: served for free
  EXPECT_FALSE(queue.Next().has_value());
  EXPECT_TRUE(queue.CanAfford(10));
}

TEST(GlobalSearchQueueTest, PairsAreCountedApart) {
  GlobalSearchQueue queue;
  queue.CountPair(kA, kB, 2);
  queue.CountPair(kA, kB, 2);
  queue.CountPair(kB, kA, 1);
  EXPECT_EQ(queue.PairSearches(kA, kB), 4);
  EXPECT_EQ(queue.PairSearches(kB, kA), 1);
  EXPECT_EQ(queue.PairSearches(kA, kC), 0);
}

TEST(GlobalSearchQueueTest, BadOptionsAreRefused) {
  EXPECT_TRUE(Budget(0.0, 1.0).Validate().ok());
  EXPECT_FALSE(Budget(-1.0, 10.0).Validate().ok());
  EXPECT_FALSE(Budget(1.0, 0.5).Validate().ok());
  EXPECT_FALSE(Budget(std::numeric_limits<double>::infinity(), 10.0).Validate().ok());
}

}  // namespace
}  // namespace anchormap
