#include "common/scan_matching/pose_refinement.h"

#include <cmath>
#include <cstring>
#include <limits>
#include <random>
#include <vector>

#include <gtest/gtest.h>

#include "common/geometry/angle.h"
#include "tests/scan_testing/synthetic_world.h"

namespace anchormap {
namespace {

// The same double, bit for bit (EXPECT_EQ would take -0 for +0).
bool SameBits(double a, double b) { return std::memcmp(&a, &b, sizeof(double)) == 0; }

TEST(AnchoredCostTest, ManyPosesAtOnceGiveEachPosesCostToTheBit) {
  // A room's scan against another from nearby; the poses: a score distribution's lattice
  // around the true pose (points on walls, lone returns, points past a wall's end, anchored
  // inliers), wider offsets (outliers, points leaving the grid), non-finite poses, and an odd
  // count (the lookups' last lanes go one at a time).
  std::mt19937_64 rng(5);
  std::uniform_real_distribution<double> unit(-1.0, 1.0);
  const testing::SyntheticWorld world = testing::RandomRoom(31);
  testing::SyntheticLaser laser;
  laser.beams = 181;
  laser.fov_rad = kPi;
  int compared = 0;
  for (int trial = 0; trial < 6; ++trial) {
    const Pose2 a = testing::RandomFreePose(world, 0.8, &rng);
    const Pose2 b = Compose(a, Pose2(0.2 * unit(rng), 0.2 * unit(rng), 0.1 * unit(rng)));
    const PointCloud reference = ScanToPointCloud(testing::SimulateScan(world, laser, a, &rng));
    const PointCloud query = ScanToPointCloud(testing::SimulateScan(world, laser, b, &rng));
    const ReferenceField field({reference}, ReferenceFieldOptions{});
    const Pose2 truth = Between(a, b);
    const AnchoredCost cost(field, query, truth, 0.1);
    std::vector<Pose2> poses;
    for (int i = -2; i <= 2; ++i) {
      for (int j = -2; j <= 2; ++j) {
        for (int k = -2; k <= 2; ++k) {
          poses.push_back(
              Pose2::FromVector(truth.vector() + Eigen::Vector3d(0.01 * i, 0.01 * j, 0.004 * k)));
        }
      }
    }
    for (int i = 0; i < 40; ++i) {
      const double scale = i < 20 ? 0.2 : 20.0;
      poses.push_back(Compose(truth, Pose2(scale * unit(rng), scale * unit(rng), unit(rng))));
    }
    poses.push_back(Pose2(std::nan(""), 0.0, 0.0));
    poses.push_back(Pose2(0.0, std::numeric_limits<double>::infinity(), 0.0));
    ASSERT_EQ(poses.size() % 2, 1u);
    const std::vector<double> costs = cost(poses);
    ASSERT_EQ(costs.size(), poses.size());
    for (size_t i = 0; i < poses.size(); ++i) {
      const double one = cost(poses[i]);
      EXPECT_TRUE(SameBits(costs[i], one)) << i << ": " << costs[i] << " vs " << one;
      ++compared;
    }
    // The cost is the truncated one: near the truth well under every point an outlier.
    EXPECT_LT(costs[62], 0.25 * 0.01 * static_cast<double>(query.size()));
  }
  EXPECT_EQ(compared, 6 * 167);
  // No poses: no costs.
  const PointCloud none;
  const ReferenceField empty(std::vector<PointCloud>{}, ReferenceFieldOptions{});
  EXPECT_TRUE(AnchoredCost(empty, none, Pose2(), 0.1)(std::vector<Pose2>{}).empty());
}

}  // namespace
}  // namespace anchormap
