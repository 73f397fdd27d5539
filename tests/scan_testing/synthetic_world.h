#pragma once
// Test utilities for scan matching: a floor plan of wall segments, an exact brute-force ray
// caster with Gaussian range noise, and seeded random rooms (an outer rectangle with pillars
// and partitions, so that no two places look alike). Deterministic for a given seed.

#include <cstdint>
#include <random>
#include <vector>

#include <Eigen/Core>

#include "common/geometry/pose2.h"
#include "common/types/laser_scan.h"

namespace anchormap::testing {

struct Segment {
  Eigen::Vector2d a;
  Eigen::Vector2d b;
};

struct SyntheticWorld {
  std::vector<Segment> walls;
  Eigen::Vector2d min_corner{0.0, 0.0};
  Eigen::Vector2d max_corner{0.0, 0.0};

  // The four walls of the axis-aligned rectangle [lo, hi], counter-clockwise from lo.
  void AddBox(const Eigen::Vector2d& lo, const Eigen::Vector2d& hi);
  void AddBox(double x0, double y0, double x1, double y1) {
    AddBox(Eigen::Vector2d(x0, y0), Eigen::Vector2d(x1, y1));
  }
  // Distance along the ray from `origin` at `angle` to the first wall; +inf when none.
  double RayCast(const Eigen::Vector2d& origin, double angle) const;
  double DistanceToNearestWall(const Eigen::Vector2d& p) const;
};

// An outer rectangle of 10-16 m by 8-12 m with 4-7 rectangular pillars and 2-4 partitions.
SyntheticWorld RandomRoom(uint64_t seed);

struct SyntheticLaser {
  int beams = 360;
  double fov_rad = 2.0 * 3.14159265358979323846;  // centred on the sensor's heading
  double max_range_m = 30.0;
  double range_sigma_m = 0.01;
  Pose2 T_body_sensor;
};

// 181 beams over half a circle, as the benchmark logs' SICK lasers.
inline SyntheticLaser HalfCircleLaser(double max_range_m = 30.0) {
  SyntheticLaser laser;
  laser.beams = 181;
  laser.fov_rad = 3.14159265358979323846;
  laser.max_range_m = max_range_m;
  return laser;
}

// A scan from the robot body at T_world_body. Range noise is drawn from `rng`; beams without a
// wall within range read max_range (no return).
LaserScan SimulateScan(const SyntheticWorld& world, const SyntheticLaser& laser,
                       const Pose2& T_world_body, std::mt19937_64* rng);

// A random pose inside the room at least `clearance_m` from every wall.
Pose2 RandomFreePose(const SyntheticWorld& world, double clearance_m, std::mt19937_64* rng);

}  // namespace anchormap::testing
