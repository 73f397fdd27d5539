#include "common/scan_matching/global_search.h"

#include <cmath>
#include <cstdio>
#include <random>

#include <gtest/gtest.h>

#include "common/geometry/angle.h"
#include "tests/scan_testing/synthetic_world.h"

namespace anchormap {
namespace {

using testing::RandomFreePose;
using testing::RandomRoom;
using testing::SimulateScan;
using testing::SyntheticLaser;
using testing::SyntheticWorld;

constexpr double kDeg = kPi / 180.0;

// A map of `scans` scans taken at random free poses, in the world frame.
std::vector<PointCloud> MapScans(const SyntheticWorld& world, const SyntheticLaser& laser,
                                 int scans, std::mt19937_64* rng) {
  std::vector<PointCloud> map;
  for (int i = 0; i < scans; ++i) {
    const Pose2 pose = RandomFreePose(world, 0.8, rng);
    map.push_back(
        TransformPointCloud(ScanToPointCloud(SimulateScan(world, laser, pose, rng)), pose));
  }
  return map;
}

TEST(GlobalSearchTest, FindsTheTransformFromUnknownStarts) {
  // Six seeded rooms, a map of four 360-beam scans each, and three queries per room from
  // random free poses with random headings (no prior at all). Each must be found within 2 cm
  // and 0.5 degree, with a score above the global default bar of 0.5.
  SyntheticLaser laser;
  laser.beams = 360;
  laser.range_sigma_m = 0.01;
  laser.T_body_sensor = Pose2(0.15, 0.0, 0.0);
  std::mt19937_64 rng(21);
  int found = 0;
  for (uint64_t seed = 0; seed < 6; ++seed) {
    const SyntheticWorld world = RandomRoom(500 + seed);
    const ScanReference reference(MapScans(world, laser, 4, &rng), ScanReferenceOptions{});
    for (int q = 0; q < 3; ++q) {
      const Pose2 truth = RandomFreePose(world, 0.8, &rng);
      const PointCloud query = ScanToPointCloud(SimulateScan(world, laser, truth, &rng));
      const std::optional<MatchResult> match =
          GlobalSearch(reference, query, GlobalSearchOptions{});
      ASSERT_TRUE(match.has_value()) << "room " << seed << " query " << q;
      const Eigen::Vector3d error = PoseError(truth, match->pose);
      EXPECT_LT(error.head<2>().norm(), 0.02) << "room " << seed << " query " << q;
      EXPECT_LT(std::abs(error.z()), 0.5 * kDeg) << "room " << seed << " query " << q;
      EXPECT_GT(match->score, 0.5);
      if (error.head<2>().norm() < 0.02) ++found;
    }
  }
  EXPECT_EQ(found, 18);
}

TEST(GlobalSearchTest, BranchAndBoundEqualsExhaustiveSearchOnScans) {
  // On a real likelihood grid (a coarse one, so that exhaustive search stays cheap): the same
  // best score as scoring every lattice pose, over a quarter turn and the whole grid.
  SyntheticLaser laser;
  laser.beams = 180;
  std::mt19937_64 rng(22);
  for (uint64_t seed = 0; seed < 3; ++seed) {
    const SyntheticWorld world = RandomRoom(600 + seed);
    ScanReferenceOptions options;
    options.resolution_m = 0.2;
    options.likelihood_sigma_m = 0.2;
    options.num_levels = 4;
    const ScanReference reference(MapScans(world, laser, 2, &rng), options);
    const PointCloud query =
        ScanToPointCloud(SimulateScan(world, laser, RandomFreePose(world, 0.8, &rng), &rng));
    SearchWindow window = GlobalSearchWindow(reference, query);
    window.half_angles = std::min(window.half_angles, 20);
    const DiscretisedQuery discretised(query, window, reference.geometry());
    LatticeSearchStats all_stats;
    LatticeSearchStats bnb_stats;
    const auto all = ExhaustiveSearch(reference.pyramid(), discretised, window, 0.0, &all_stats);
    const auto bnb = BranchAndBound(reference.pyramid(), discretised, window, 0.0, &bnb_stats);
    ASSERT_TRUE(all.has_value());
    ASSERT_TRUE(bnb.has_value());
    EXPECT_EQ(all->score, bnb->score) << "room " << seed;
    std::printf("leaves: exhaustive %lld, branch and bound %lld\n",
                static_cast<long long>(all_stats.leaves), static_cast<long long>(bnb_stats.leaves));
    EXPECT_LT(bnb_stats.leaves, all_stats.leaves / 10);
  }
}

TEST(GlobalSearchTest, EmptyInputsFindNothing) {
  const ScanReference empty(std::vector<PointCloud>{}, ScanReferenceOptions{});
  EXPECT_FALSE(GlobalSearch(empty, {{1.0, 0.0}}, GlobalSearchOptions{}).has_value());
  const ScanReference one({{{1.0, 0.0}, {1.0, 0.1}}}, ScanReferenceOptions{});
  EXPECT_FALSE(GlobalSearch(one, {}, GlobalSearchOptions{}).has_value());
}

}  // namespace
}  // namespace anchormap
