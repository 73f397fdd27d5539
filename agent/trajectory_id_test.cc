#include "agent/trajectory_id.h"

#include <set>
#include <thread>
#include <vector>

#include <gtest/gtest.h>

namespace anchormap {
namespace {

TEST(TrajectoryIdTest, AThousandSimultaneousDrawsAreDistinctAndPositive) {
  // 1000 "agents" starting at once: 8 threads drawing together.
  constexpr int kThreads = 8, kPerThread = 125;
  std::vector<std::vector<int64_t>> drawn(kThreads);
  std::vector<std::thread> threads;
  for (int t = 0; t < kThreads; ++t) {
    threads.emplace_back([&drawn, t] {
      for (int i = 0; i < kPerThread; ++i) drawn[t].push_back(DrawTrajectoryId());
    });
  }
  for (std::thread& thread : threads) thread.join();
  std::set<int64_t> ids;
  for (const auto& list : drawn) {
    for (int64_t id : list) {
      EXPECT_GT(id, 0);
      ids.insert(id);
    }
  }
  EXPECT_EQ(ids.size(), static_cast<size_t>(kThreads * kPerThread));
}

}  // namespace
}  // namespace anchormap
