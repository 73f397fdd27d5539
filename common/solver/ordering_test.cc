#include "common/solver/ordering.h"

#include <algorithm>
#include <random>
#include <vector>

#include <gtest/gtest.h>

namespace anchormap {
namespace {

// A chain of poses with random loop closures, a factor that lists a variable twice, and
// some variables constrained last: the shape of a pose graph's pattern.
struct Pattern {
  int num_variables = 0;
  std::vector<std::vector<int>> factors;
  std::vector<bool> keep_last;
};

Pattern RandomPattern(unsigned seed) {
  std::mt19937 rng(seed);
  Pattern pattern;
  pattern.num_variables = 60;
  pattern.factors.push_back({0});
  for (int v = 1; v < pattern.num_variables; ++v) pattern.factors.push_back({v - 1, v});
  std::uniform_int_distribution<int> pick(0, pattern.num_variables - 1);
  for (int k = 0; k < 25; ++k) pattern.factors.push_back({pick(rng), pick(rng), pick(rng)});
  pattern.factors.push_back({7, 7});
  pattern.keep_last.assign(pattern.num_variables, false);
  for (int v : {3, 31, 59}) pattern.keep_last[v] = true;
  return pattern;
}

TEST(OrderingTest, FlatAndNestedFormsGiveTheSameConstrainedPermutation) {
  for (unsigned seed = 1; seed <= 5; ++seed) {
    const Pattern pattern = RandomPattern(seed);
    std::vector<int> start(1, 0), variables;
    for (const std::vector<int>& factor : pattern.factors) {
      variables.insert(variables.end(), factor.begin(), factor.end());
      start.push_back(static_cast<int>(variables.size()));
    }
    const Result<std::vector<int>> nested =
        ComputeOrdering(pattern.num_variables, pattern.factors, pattern.keep_last);
    const Result<std::vector<int>> flat =
        ComputeOrdering(pattern.num_variables, start, variables, pattern.keep_last);
    ASSERT_TRUE(nested.ok());
    ASSERT_TRUE(flat.ok());
    EXPECT_EQ(*nested, *flat);
    // A permutation of all variables, with the constrained ones in the last three places.
    std::vector<int> sorted = *flat;
    std::sort(sorted.begin(), sorted.end());
    for (int v = 0; v < pattern.num_variables; ++v) ASSERT_EQ(sorted[v], v);
    for (int k = 0; k < pattern.num_variables; ++k) {
      EXPECT_EQ(pattern.keep_last[(*flat)[k]], k >= pattern.num_variables - 3) << "position " << k;
    }
  }
}

TEST(OrderingTest, InjectedFailureIsReportedByTheFlatForm) {
  FailNextOrderingsForTesting(1);
  const Result<std::vector<int>> order = ComputeOrdering(2, {0, 2}, {0, 1}, {false, true});
  EXPECT_FALSE(order.ok());
  EXPECT_TRUE(ComputeOrdering(2, {0, 2}, {0, 1}, {false, true}).ok());
}

}  // namespace
}  // namespace anchormap
