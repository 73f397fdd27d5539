#include "tests/scan_testing/synthetic_world.h"

#include <algorithm>
#include <cmath>
#include <limits>

namespace anchormap::testing {

namespace {

double Cross(const Eigen::Vector2d& a, const Eigen::Vector2d& b) {
  return a.x() * b.y() - a.y() * b.x();
}

}  // namespace

void SyntheticWorld::AddBox(const Eigen::Vector2d& lo, const Eigen::Vector2d& hi) {
  const Eigen::Vector2d c1(hi.x(), lo.y());
  const Eigen::Vector2d c3(lo.x(), hi.y());
  walls.push_back({lo, c1});
  walls.push_back({c1, hi});
  walls.push_back({hi, c3});
  walls.push_back({c3, lo});
}

double SyntheticWorld::RayCast(const Eigen::Vector2d& origin, double angle) const {
  const Eigen::Vector2d d(std::cos(angle), std::sin(angle));
  double best = std::numeric_limits<double>::infinity();
  for (const Segment& w : walls) {
    const Eigen::Vector2d e = w.b - w.a;
    const double denom = Cross(d, e);
    if (std::abs(denom) < 1e-12) continue;
    const Eigen::Vector2d ao = w.a - origin;
    const double t = Cross(ao, e) / denom;
    const double u = Cross(ao, d) / denom;
    if (t > 0.0 && u >= 0.0 && u <= 1.0) best = std::min(best, t);
  }
  return best;
}

double SyntheticWorld::DistanceToNearestWall(const Eigen::Vector2d& p) const {
  double best = std::numeric_limits<double>::infinity();
  for (const Segment& w : walls) {
    const Eigen::Vector2d e = w.b - w.a;
    const double t = std::clamp((p - w.a).dot(e) / e.squaredNorm(), 0.0, 1.0);
    best = std::min(best, (w.a + t * e - p).norm());
  }
  return best;
}

SyntheticWorld RandomRoom(uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  SyntheticWorld world;
  const double w = 10.0 + 6.0 * unit(rng);
  const double h = 8.0 + 4.0 * unit(rng);
  world.min_corner = {0.0, 0.0};
  world.max_corner = {w, h};
  world.AddBox(world.min_corner, world.max_corner);
  const int pillars = 4 + static_cast<int>(unit(rng) * 4.0);
  for (int i = 0; i < pillars; ++i) {
    // One draw per statement: a call's argument order is unspecified (gcc's order kept).
    const double size_y = 0.3 + 0.9 * unit(rng);
    const double size_x = 0.3 + 0.9 * unit(rng);
    const Eigen::Vector2d size(size_x, size_y);
    const double lo_y = 1.0 + (h - 2.0 - size.y()) * unit(rng);
    const double lo_x = 1.0 + (w - 2.0 - size.x()) * unit(rng);
    const Eigen::Vector2d lo(lo_x, lo_y);
    world.AddBox(lo, lo + size);
  }
  const int partitions = 2 + static_cast<int>(unit(rng) * 3.0);
  for (int i = 0; i < partitions; ++i) {
    // A partition from a wall into the room, at a random angle.
    const bool from_bottom = unit(rng) < 0.5;
    const double x = 1.0 + (w - 2.0) * unit(rng);
    const double length = 1.5 + 2.0 * unit(rng);
    const double angle = (from_bottom ? 1.0 : -1.0) * (0.9 + 1.3 * unit(rng));
    const Eigen::Vector2d a(x, from_bottom ? 0.0 : h);
    world.walls.push_back({a, a + length * Eigen::Vector2d(std::cos(angle), std::sin(angle))});
  }
  return world;
}

LaserScan SimulateScan(const SyntheticWorld& world, const SyntheticLaser& laser,
                       const Pose2& T_world_body, std::mt19937_64* rng) {
  LaserScan scan;
  scan.T_body_sensor = laser.T_body_sensor;
  scan.max_range = static_cast<float>(laser.max_range_m);
  const bool full_circle = laser.fov_rad >= 2.0 * 3.14159265358979323846 - 1e-9;
  scan.radstep = static_cast<float>(laser.fov_rad / (full_circle ? laser.beams : laser.beams - 1));
  scan.rad0 = static_cast<float>(-0.5 * laser.fov_rad);
  const Pose2 T_world_sensor = Compose(T_world_body, laser.T_body_sensor);
  std::normal_distribution<double> noise(0.0, laser.range_sigma_m);
  scan.ranges.resize(laser.beams);
  for (int i = 0; i < laser.beams; ++i) {
    const double angle = T_world_sensor.theta() + scan.Angle(i);
    const double r = world.RayCast(T_world_sensor.translation(), angle);
    const double n = noise(*rng);
    scan.ranges[i] = r < laser.max_range_m ? static_cast<float>(r + n) : scan.max_range;
  }
  return scan;
}

Pose2 RandomFreePose(const SyntheticWorld& world, double clearance_m, std::mt19937_64* rng) {
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  for (;;) {
    // One draw per statement: a call's argument order is unspecified (gcc's order kept).
    const double v = unit(*rng);
    const double u = unit(*rng);
    const Eigen::Vector2d p =
        world.min_corner +
        (world.max_corner - world.min_corner).cwiseProduct(Eigen::Vector2d(u, v));
    if (world.DistanceToNearestWall(p) < clearance_m) continue;
    return Pose2(p.x(), p.y(), (2.0 * unit(*rng) - 1.0) * 3.14159265358979323846);
  }
}

}  // namespace anchormap::testing
