#pragma once
// The simulated world: a set of wall segments in the world frame (metres) with a uniform
// bucket grid, so that a ray cast visits only the buckets along the ray (Amanatides-Woo
// traversal) instead of every wall. Ray casting is exact: the distance to the first wall
// is computed analytically, which is what the laser test compares against.

#include <limits>
#include <vector>

#include <Eigen/Core>

namespace anchormap::sim {

struct WallSegment {
  Eigen::Vector2d a;
  Eigen::Vector2d b;
};

class World {
 public:
  // `bucket_size_m` trades memory for ray-cast speed; about a corridor's width is good.
  explicit World(std::vector<WallSegment> walls, double bucket_size_m = 1.0);

  const std::vector<WallSegment>& walls() const { return walls_; }
  // Axis-aligned bounds of all walls.
  const Eigen::Vector2d& min_corner() const { return min_corner_; }
  const Eigen::Vector2d& max_corner() const { return max_corner_; }

  // Distance in metres from `origin` along the unit direction of `angle_rad` (world
  // frame) to the first wall, or +infinity when no wall lies within `max_range_m`.
  // A ray that grazes a wall end point exactly counts as a hit.
  double RayCast(const Eigen::Vector2d& origin, double angle_rad, double max_range_m) const;

  // True when the straight line from `from` to `to` crosses no wall.
  bool LineOfSight(const Eigen::Vector2d& from, const Eigen::Vector2d& to) const;

  // Euclidean distance from `point` to the nearest wall (brute force; for tests and checks).
  double DistanceToNearestWall(const Eigen::Vector2d& point) const;

  static constexpr double kNoHit = std::numeric_limits<double>::infinity();

 private:
  int BucketIndex(int ix, int iy) const { return iy * buckets_x_ + ix; }

  std::vector<WallSegment> walls_;
  Eigen::Vector2d min_corner_{0.0, 0.0};
  Eigen::Vector2d max_corner_{0.0, 0.0};
  Eigen::Vector2d grid_origin_{0.0, 0.0};
  double bucket_size_m_ = 1.0;
  int buckets_x_ = 0;
  int buckets_y_ = 0;
  std::vector<std::vector<int>> buckets_;  // wall indices per bucket, row-major
};

// Distance from `point` to the segment [a, b].
double PointSegmentDistance(const Eigen::Vector2d& point, const Eigen::Vector2d& a,
                            const Eigen::Vector2d& b);

}  // namespace anchormap::sim
