#include "tools/sim/world.h"

#include <algorithm>
#include <cmath>

namespace anchormap::sim {
namespace {

double Cross(const Eigen::Vector2d& u, const Eigen::Vector2d& v) {
  return u.x() * v.y() - u.y() * v.x();
}

// Ray origin + t * direction against segment [a, b]: t of the hit, or kNoHit. Parallel
// rays never hit (a ray sliding along a wall sees the walls it ends on instead). The
// small tolerance on the segment parameter closes the gap where two walls meet.
double RaySegment(const Eigen::Vector2d& origin, const Eigen::Vector2d& direction,
                  const WallSegment& wall) {
  const Eigen::Vector2d edge = wall.b - wall.a;
  const double denominator = Cross(direction, edge);
  if (std::abs(denominator) < 1e-12 * std::max(1.0, edge.norm())) return World::kNoHit;
  const Eigen::Vector2d to_a = wall.a - origin;
  const double t = Cross(to_a, edge) / denominator;
  const double u = Cross(to_a, direction) / denominator;
  constexpr double kTolerance = 1e-9;
  if (t < 0.0 || u < -kTolerance || u > 1.0 + kTolerance) return World::kNoHit;
  return t;
}

}  // namespace

double PointSegmentDistance(const Eigen::Vector2d& point, const Eigen::Vector2d& a,
                            const Eigen::Vector2d& b) {
  const Eigen::Vector2d edge = b - a;
  const double length_sq = edge.squaredNorm();
  if (length_sq <= 0.0) return (point - a).norm();
  const double s = std::clamp((point - a).dot(edge) / length_sq, 0.0, 1.0);
  return (point - (a + s * edge)).norm();
}

World::World(std::vector<WallSegment> walls, double bucket_size_m)
    : walls_(std::move(walls)), bucket_size_m_(bucket_size_m > 0.0 ? bucket_size_m : 1.0) {
  if (walls_.empty()) return;
  min_corner_ = walls_.front().a;
  max_corner_ = walls_.front().a;
  for (const WallSegment& wall : walls_) {
    min_corner_ = min_corner_.cwiseMin(wall.a).cwiseMin(wall.b);
    max_corner_ = max_corner_.cwiseMax(wall.a).cwiseMax(wall.b);
  }
  // One bucket of margin on each side so that walls on the bounds are inside the grid.
  grid_origin_ = min_corner_ - Eigen::Vector2d::Constant(bucket_size_m_);
  const Eigen::Vector2d extent = max_corner_ - grid_origin_;
  buckets_x_ = static_cast<int>(std::floor(extent.x() / bucket_size_m_)) + 2;
  buckets_y_ = static_cast<int>(std::floor(extent.y() / bucket_size_m_)) + 2;
  buckets_.assign(static_cast<size_t>(buckets_x_) * buckets_y_, {});
  // Every bucket the segment's slightly grown bounding box touches: walls lying exactly
  // on a bucket border are filed in both neighbours.
  constexpr double kGrow = 1e-9;
  for (size_t i = 0; i < walls_.size(); ++i) {
    const Eigen::Vector2d low = walls_[i].a.cwiseMin(walls_[i].b) - grid_origin_;
    const Eigen::Vector2d high = walls_[i].a.cwiseMax(walls_[i].b) - grid_origin_;
    const int x0 = static_cast<int>(std::floor((low.x() - kGrow) / bucket_size_m_));
    const int x1 = static_cast<int>(std::floor((high.x() + kGrow) / bucket_size_m_));
    const int y0 = static_cast<int>(std::floor((low.y() - kGrow) / bucket_size_m_));
    const int y1 = static_cast<int>(std::floor((high.y() + kGrow) / bucket_size_m_));
    for (int iy = std::max(0, y0); iy <= std::min(buckets_y_ - 1, y1); ++iy) {
      for (int ix = std::max(0, x0); ix <= std::min(buckets_x_ - 1, x1); ++ix) {
        buckets_[BucketIndex(ix, iy)].push_back(static_cast<int>(i));
      }
    }
  }
}

double World::RayCast(const Eigen::Vector2d& origin, double angle_rad, double max_range_m) const {
  if (walls_.empty() || !(max_range_m > 0.0)) return kNoHit;
  const Eigen::Vector2d direction(std::cos(angle_rad), std::sin(angle_rad));
  const Eigen::Vector2d grid_max =
      grid_origin_ + Eigen::Vector2d(buckets_x_, buckets_y_) * bucket_size_m_;

  // Clip the ray to the grid box (slab method); the traversal starts where it enters.
  double t_enter = 0.0;
  double t_leave = max_range_m;
  for (int axis = 0; axis < 2; ++axis) {
    if (direction[axis] == 0.0) {
      if (origin[axis] < grid_origin_[axis] || origin[axis] > grid_max[axis]) return kNoHit;
      continue;
    }
    double t0 = (grid_origin_[axis] - origin[axis]) / direction[axis];
    double t1 = (grid_max[axis] - origin[axis]) / direction[axis];
    if (t0 > t1) std::swap(t0, t1);
    t_enter = std::max(t_enter, t0);
    t_leave = std::min(t_leave, t1);
  }
  if (t_enter > t_leave) return kNoHit;

  const Eigen::Vector2d start = (origin + t_enter * direction - grid_origin_) / bucket_size_m_;
  int ix = std::clamp(static_cast<int>(std::floor(start.x())), 0, buckets_x_ - 1);
  int iy = std::clamp(static_cast<int>(std::floor(start.y())), 0, buckets_y_ - 1);
  const int step_x = direction.x() > 0.0 ? 1 : -1;
  const int step_y = direction.y() > 0.0 ? 1 : -1;
  // Ray parameter at which the next vertical / horizontal bucket border is crossed.
  auto next_border = [&](int axis, int index, int step) {
    if (direction[axis] == 0.0) return kNoHit;
    const double border = grid_origin_[axis] + (index + (step > 0 ? 1 : 0)) * bucket_size_m_;
    return (border - origin[axis]) / direction[axis];
  };
  double t_next_x = next_border(0, ix, step_x);
  double t_next_y = next_border(1, iy, step_y);
  const double t_delta_x = direction.x() == 0.0 ? kNoHit : bucket_size_m_ / std::abs(direction.x());
  const double t_delta_y = direction.y() == 0.0 ? kNoHit : bucket_size_m_ / std::abs(direction.y());

  double best = kNoHit;
  while (true) {
    for (int wall_index : buckets_[BucketIndex(ix, iy)]) {
      best = std::min(best, RaySegment(origin, direction, walls_[wall_index]));
    }
    const double t_bucket_exit = std::min(t_next_x, t_next_y);
    // A hit inside this bucket cannot be beaten by a wall further along the ray.
    if (best <= t_bucket_exit || t_bucket_exit > t_leave) break;
    if (t_next_x < t_next_y) {
      ix += step_x;
      t_next_x += t_delta_x;
      if (ix < 0 || ix >= buckets_x_) break;
    } else {
      iy += step_y;
      t_next_y += t_delta_y;
      if (iy < 0 || iy >= buckets_y_) break;
    }
  }
  return best <= max_range_m ? best : kNoHit;
}

bool World::LineOfSight(const Eigen::Vector2d& from, const Eigen::Vector2d& to) const {
  const Eigen::Vector2d delta = to - from;
  const double distance = delta.norm();
  if (distance <= 0.0) return true;
  const double hit = RayCast(from, std::atan2(delta.y(), delta.x()), distance);
  return hit == kNoHit || hit >= distance - 1e-9;
}

double World::DistanceToNearestWall(const Eigen::Vector2d& point) const {
  double best = kNoHit;
  for (const WallSegment& wall : walls_) {
    best = std::min(best, PointSegmentDistance(point, wall.a, wall.b));
  }
  return best;
}

}  // namespace anchormap::sim
