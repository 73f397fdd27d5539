#include "common/scan_matching/flat_direction.h"

#include <cmath>
#include <cstdio>
#include <random>
#include <utility>

#include <gtest/gtest.h>

#include "common/geometry/angle.h"
#include "common/scan_matching/scan_reference.h"
#include "tests/scan_testing/synthetic_world.h"

namespace anchormap {
namespace {

using testing::HalfCircleLaser;
using testing::RandomFreePose;
using testing::RandomRoom;
using testing::SimulateScan;
using testing::SyntheticLaser;
using testing::SyntheticWorld;

ScanReferenceOptions LocalReferenceOptions() {
  ScanReferenceOptions options;
  options.num_levels = 4;
  return options;
}

// A scan in a random room and the next one 0.2 m on, as a local map's reference and a query
// with its true pose in the reference's frame.
struct RoomScans {
  ScanReference reference;
  PointCloud query;
  Pose2 truth;
};

RoomScans ScansInARandomRoom(uint64_t seed) {
  std::mt19937_64 rng(seed);
  const SyntheticWorld room = RandomRoom(seed);
  const Pose2 a = RandomFreePose(room, 0.8, &rng);
  const Pose2 b = Compose(a, Pose2(0.2, -0.1, 0.05));
  const SyntheticLaser laser = HalfCircleLaser(30.0);
  ScanReference reference({ScanToPointCloud(SimulateScan(room, laser, a, &rng))},
                          LocalReferenceOptions());
  PointCloud query = ScanToPointCloud(SimulateScan(room, laser, b, &rng));
  return {std::move(reference), std::move(query), Between(a, b)};
}

// The axis's angle from the x axis, folded into [0, pi).
double AxisAngle(const Eigen::Vector2d& axis) {
  const double a = std::atan2(axis.y(), axis.x());
  return a < 0.0 ? a + kPi : a;
}

TEST(FlatDirectionTest, FindsACorridorsAxis) {
  // A plain corridor 2.4 m wide running at 0.3 rad, longer than the laser's 8 m reach: a shift
  // along it leaves every point on its wall. Query and reference are scans 0.5 m apart, the
  // query at its true pose in the reference's frame.
  for (const double axis_angle : {0.3, 1.9}) {
    const Eigen::Vector2d u(std::cos(axis_angle), std::sin(axis_angle));
    const Eigen::Vector2d n(-u.y(), u.x());
    SyntheticWorld corridor;
    corridor.walls = {{-60.0 * u, 60.0 * u}, {-60.0 * u + 2.4 * n, 60.0 * u + 2.4 * n}};
    corridor.min_corner = -60.0 * u.cwiseAbs() - 2.4 * n.cwiseAbs();
    corridor.max_corner = 60.0 * u.cwiseAbs() + 2.4 * n.cwiseAbs();
    std::mt19937_64 rng(31);
    const Eigen::Vector2d pa = 1.1 * n;
    const Eigen::Vector2d pb = 0.5 * u + 1.3 * n;
    const Pose2 a(pa.x(), pa.y(), axis_angle + 0.1);
    const Pose2 b(pb.x(), pb.y(), axis_angle - 0.05);
    const SyntheticLaser laser = HalfCircleLaser(8.0);
    const ScanReference reference({ScanToPointCloud(SimulateScan(corridor, laser, a, &rng))},
                                  LocalReferenceOptions());
    const PointCloud query = ScanToPointCloud(SimulateScan(corridor, laser, b, &rng));
    const auto flat = FindFlatDirection(reference, query, Between(a, b), FlatDirectionOptions{});
    ASSERT_TRUE(flat.has_value());
    // In a's frame the corridor runs at -0.1 rad.
    const double error = std::abs(WrapAngle(2.0 * (AxisAngle(flat->axis) + 0.1))) / 2.0;
    std::printf("corridor at %.1f rad: axis off by %.2f deg, score ratio %.3f\n", axis_angle,
                error * 180.0 / kPi, flat->score_ratio);
    EXPECT_LT(error, 2.0 * kPi / 180.0);
    EXPECT_GT(flat->score_ratio, 0.95);
  }
}

TEST(FlatDirectionTest, RoomsHaveNone) {
  // In a room every direction moves points off walls within a few centimetres.
  int rooms = 0;
  for (uint64_t seed = 0; seed < 6; ++seed) {
    const auto [reference, query, truth] = ScansInARandomRoom(40 + seed);
    const auto most = MostFlatDirection(reference, query, truth, FlatDirectionOptions{});
    ASSERT_TRUE(most.has_value());
    std::printf("room %d: most flat score ratio %.3f\n", static_cast<int>(seed), most->score_ratio);
    EXPECT_LT(most->score_ratio, 0.8);
    EXPECT_FALSE(FindFlatDirection(reference, query, truth, FlatDirectionOptions{}).has_value());
    ++rooms;
  }
  EXPECT_EQ(rooms, 6);
}

TEST(FlatDirectionTest, ShiftedWallScoreAboveIsTheScoreToTheBitOrAtMostTheFloor) {
  // The flat search asks only whether a shift beats the best direction so far: above the floor
  // the score is finished (the same bits), below it may stop early with a value at most the
  // floor. Shifts all round at 0.1 and 0.4 m in a room, floors from 0 to past the top.
  const auto [reference, query, truth] = ScansInARandomRoom(52);
  const ReferenceField& field = reference.field();
  const std::vector<WallPoint> on_walls = PointsOnWalls(field, query, truth);
  ASSERT_GT(on_walls.size(), 50u);
  const double sigma = reference.options().likelihood_sigma_m;
  int finished = 0;
  int stopped = 0;
  for (int i = 0; i < 36; ++i) {
    const double angle = i * kPi / 18.0;
    for (const double reach : {0.1, 0.4}) {
      const Eigen::Vector2d shift = reach * Eigen::Vector2d(std::cos(angle), std::sin(angle));
      const double full = ShiftedWallScore(field, on_walls, shift, sigma);
      for (const double floor : {0.0, 0.2, 0.4, 0.6, 0.8, 1.1, full}) {
        const double above = ShiftedWallScoreAbove(field, on_walls, shift, sigma, floor);
        if (full > floor) {
          EXPECT_EQ(above, full);
          ++finished;
        } else {
          EXPECT_LE(above, floor);
          ++stopped;
        }
      }
    }
  }
  EXPECT_GT(finished, 50);
  EXPECT_GT(stopped, 50);
}

}  // namespace
}  // namespace anchormap
