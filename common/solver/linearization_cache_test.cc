#include "common/solver/linearization_cache.h"

#include <cstring>
#include <random>
#include <vector>

#include <gtest/gtest.h>

namespace anchormap {
namespace {

bool SameBits(const LinearizedView& a, const LinearizedFactor& b) {
  if (a.num_keys() != b.num_keys) return false;
  for (int j = 0; j < a.num_keys(); ++j) {
    if (std::memcmp(a.jacobian(j).data(), b.jacobians[j].data(), 9 * sizeof(double)) != 0) {
      return false;
    }
  }
  return std::memcmp(a.whitened_error().data(), b.whitened_error.data(), 3 * sizeof(double)) == 0;
}

// The gradient terms as the passes summed them before At gave them: Eigen's products.
bool SameTermBits(const double* terms, double squared, const LinearizedFactor& b) {
  for (int j = 0; j < b.num_keys; ++j) {
    const Eigen::Vector3d term = b.jacobians[j].transpose() * b.whitened_error;
    if (std::memcmp(terms + 3 * j, term.data(), 3 * sizeof(double)) != 0) return false;
  }
  const double norm2 = b.whitened_error.squaredNorm();
  return std::memcmp(&squared, &norm2, sizeof(double)) == 0;
}

// A chain of 30 poses with odometry and 10 loop closures; at each of 50 passes a few
// variables move (in x or in angle; some by one unit in the last place). Every entry equals a fresh
// linearisation bit for bit, and only factors touching a moved variable are linearised.
TEST(LinearizationCacheTest, EntriesEqualAFreshLinearisationAndOnlyMovedFactorsAreRedone) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> uniform(-1.0, 1.0);
  const int n = 30;
  std::vector<Pose2> values;
  for (int i = 0; i < n; ++i)
    values.emplace_back(i + 0.1 * uniform(rng), uniform(rng), uniform(rng));
  std::vector<Factor> factors;
  std::vector<std::array<int, 2>> vars;
  auto between = [&](int a, int b) {
    BetweenFactor f;
    f.from = PoseKey{TrajectoryId(1), a};
    f.to = PoseKey{TrajectoryId(1), b};
    f.measured_T_from_to = Pose2(1.0 + 0.1 * uniform(rng), 0.1 * uniform(rng), 0.1 * uniform(rng));
    f.sqrt_information = Eigen::Vector3d(10.0, 10.0, 30.0).asDiagonal();
    factors.push_back(f);
    vars.push_back({a, b});
  };
  for (int i = 1; i < n; ++i) between(i - 1, i);
  for (int k = 0; k < 10; ++k) between(static_cast<int>(rng() % n), static_cast<int>(rng() % n));

  LinearizationCache cache;
  int64_t expected_linearized = 0;
  std::vector<Pose2> previous;
  for (int pass = 0; pass < 50; ++pass) {
    if (pass > 0) {
      const int moves = static_cast<int>(rng() % 4);
      for (int m = 0; m < moves; ++m) {
        // x or the angle (whose cos and sin the cache keeps per variable).
        Pose2& v = values[rng() % n];
        const bool turn = rng() % 2;
        const double old = turn ? v.theta() : v.x();
        const double moved = rng() % 2 ? std::nextafter(old, 10.0) : old + 0.01;
        v = turn ? Pose2(v.x(), v.y(), moved) : Pose2(moved, v.y(), v.theta());
      }
    }
    cache.BeginPass(values, static_cast<int64_t>(factors.size()));
    for (size_t id = 0; id < factors.size(); ++id) {
      const std::array<Pose2, kMaxFactorKeys> at = {values[vars[id][0]], values[vars[id][1]]};
      const bool moved = previous.empty() ||
                         std::memcmp(&at[0], &previous[vars[id][0]], sizeof(Pose2)) != 0 ||
                         std::memcmp(&at[1], &previous[vars[id][1]], sizeof(Pose2)) != 0;
      expected_linearized += moved ? 1 : 0;
      double terms[6], squared;
      const LinearizedFactor fresh = Linearize(factors[id], at.data());
      EXPECT_TRUE(SameBits(
          cache.At(static_cast<int64_t>(id), factors[id], vars[id].data(), 2, terms, &squared),
          fresh))
          << "pass " << pass << ", factor " << id;
      EXPECT_TRUE(SameTermBits(terms, squared, fresh)) << "pass " << pass << ", factor " << id;
    }
    previous = values;
  }
  EXPECT_EQ(cache.passes(), 50);
  EXPECT_EQ(cache.linearized(), expected_linearized);
  EXPECT_LT(cache.linearized(), 50 * static_cast<int64_t>(factors.size()) / 4);
}

// A factor left out of a pass is linearised again when it is back, even if its variables
// moved only while it was out and came back to the same bits.
TEST(LinearizationCacheTest, AFactorSkippedInAPassIsLinearisedAgain) {
  BetweenFactor f;
  f.from = PoseKey{TrajectoryId(1), 0};
  f.to = PoseKey{TrajectoryId(1), 1};
  f.measured_T_from_to = Pose2(1.0, 0.0, 0.0);
  f.sqrt_information << 3.0, 0.5, -0.25, 0.0, 2.0, 0.75, 0.0, 0.0, 5.0;
  const std::array<int, 2> vars = {0, 1};
  LinearizationCache cache;
  std::vector<Pose2> values = {Pose2(0, 0, 0), Pose2(1, 0, 0)};
  cache.BeginPass(values, 1);
  double terms[6], squared;
  cache.At(0, f, vars.data(), 2, terms, &squared);
  values[1] = Pose2(2, 0, 0);
  cache.BeginPass(values, 1);
  cache.Skip(0);
  const std::array<Pose2, kMaxFactorKeys> at = {values[0], values[1]};
  cache.BeginPass(values, 1);
  EXPECT_TRUE(SameBits(cache.At(0, f, vars.data(), 2, terms, &squared), Linearize(f, at.data())));
  EXPECT_TRUE(SameTermBits(terms, squared, Linearize(f, at.data())));
  EXPECT_EQ(cache.linearized(), 2);
}

}  // namespace
}  // namespace anchormap
