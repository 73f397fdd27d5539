#include "common/scan_matching/flat_direction.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <vector>

#include "common/geometry/angle.h"

namespace anchormap {

namespace {

// Fewer query points on walls than this say nothing about a direction.
constexpr size_t kMinPointsOnWalls = 10;

// Points summed between two looks at whether the rest can still lift a shifted score above the
// best direction's so far (a power of two).
constexpr size_t kPointsBetweenStops = 16;

}  // namespace

Status FlatDirectionOptions::Validate() const {
  if (!(reach_m > 0.0) || !std::isfinite(reach_m)) return Status::Error("reach_m must be > 0");
  if (!(min_score_ratio > 0.0 && min_score_ratio <= 1.0)) {
    return Status::Error("min_score_ratio must be in (0, 1]");
  }
  if (directions < 2 || directions > 3600) return Status::Error("directions must be in [2, 3600]");
  return Status::Ok();
}

std::vector<WallPoint> PointsOnWalls(const ReferenceField& field, const PointCloud& query,
                                     const Pose2& pose) {
  std::vector<WallPoint> on_walls;
  on_walls.reserve(query.size());
  const Eigen::Matrix2d R = pose.rotation();
  const Eigen::Vector2d t = pose.translation();
  for (const Eigen::Vector2d& p : query) {
    const Eigen::Vector2d q = R * p + t;
    Eigen::Vector2d v;
    Eigen::Vector2i cell;
    int a = 0;
    int b = 0;
    Eigen::Vector2d normal;
    if (!field.InterpolateInCell(q, &v, &cell) ||
        !field.NearestPrimitive(cell.x(), cell.y(), &a, &b) || a == b ||
        !field.PrimitiveNormal(a, b, &normal)) {
      continue;
    }
    on_walls.push_back({q, q + v, normal});
  }
  return on_walls;
}

double ShiftedWallScore(const ReferenceField& field, const std::vector<WallPoint>& points,
                        const Eigen::Vector2d& shift, double sigma_m) {
  return ShiftedWallScoreAbove(field, points, shift, sigma_m,
                               -std::numeric_limits<double>::infinity());
}

namespace {

// ShiftedWallScoreAbove with the field's lookups in `at` (scratch), a chunk at a time.
double ShiftedWallScoreAbove(const ReferenceField& field, const std::vector<WallPoint>& points,
                             const Eigen::Vector2d& shift, double sigma_m, double floor,
                             ReferenceField::Lookups* at_scratch) {
  if (points.empty()) return 0.0;
  const double k = -0.5 / (sigma_m * sigma_m);
  const size_t n = points.size();
  const double count = static_cast<double>(n);
  // Each point adds at most 1; a margin far above the sum's rounding keeps the stop exact (a
  // mean above the floor is always finished, with the same additions in the same order).
  const double stop = floor * count - 1e-9 * count;
  ReferenceField::Lookups& at = *at_scratch;
  double sum = 0.0;
  for (size_t begin = 0; begin < n; begin += kPointsBetweenStops) {
    const size_t end = std::min(n, begin + kPointsBetweenStops);
    at.resize(end - begin);
    for (size_t i = begin; i < end; ++i) {
      const Eigen::Vector2d q = points[i].point + shift;
      at.qx[i - begin] = q.x();
      at.qy[i - begin] = q.y();
    }
    field.InterpolateWithNormals(&at);
    for (size_t i = begin; i < end; ++i) {
      const WallPoint& w = points[i];
      // Where the reference saw no surface near the shifted point (past the end of its view of
      // the wall, or off a feature into the open) the point keeps its own wall's line.
      const double d = at.found[i - begin]
                           ? Eigen::Vector2d(at.vx[i - begin], at.vy[i - begin]).norm()
                           : std::abs(w.normal.dot(
                                 Eigen::Vector2d(at.qx[i - begin], at.qy[i - begin]) - w.foot));
      sum += std::exp(k * d * d);
    }
    if (end < n && sum + static_cast<double>(n - end) < stop) return floor;
  }
  return sum / count;
}

}  // namespace

double ShiftedWallScoreAbove(const ReferenceField& field, const std::vector<WallPoint>& points,
                             const Eigen::Vector2d& shift, double sigma_m, double floor) {
  ReferenceField::Lookups at;
  return ShiftedWallScoreAbove(field, points, shift, sigma_m, floor, &at);
}

std::optional<FlatDirection> MostFlatDirection(const ScanReference& reference,
                                               const PointCloud& query, const Pose2& pose,
                                               const FlatDirectionOptions& options) {
  if (const Status valid = options.Validate(); !valid.ok()) {
    throw std::invalid_argument("FindFlatDirection: " + valid.message());
  }
  const ReferenceField& field = reference.field();
  const std::vector<WallPoint> on_walls = PointsOnWalls(field, query, pose);
  if (on_walls.size() < kMinPointsOnWalls) return std::nullopt;
  const double sigma = reference.options().likelihood_sigma_m;
  ReferenceField::Lookups at;
  const double at_pose = ShiftedWallScoreAbove(field, on_walls, Eigen::Vector2d::Zero(), sigma,
                                               -std::numeric_limits<double>::infinity(), &at);
  if (!(at_pose > 0.0)) return std::nullopt;
  // The smaller of the scores shifted both ways along the direction at `angle` when it is
  // above `floor` (the best direction's so far), else a value at most `floor`: only a direction
  // that beats the best is finished, so the other way is not scored once one way cannot.
  auto shifted_above = [&](double angle, double floor) {
    const Eigen::Vector2d d = options.reach_m * Eigen::Vector2d(std::cos(angle), std::sin(angle));
    const double forward = ShiftedWallScoreAbove(field, on_walls, d, sigma, floor, &at);
    if (!(forward > floor)) return forward;
    return std::min(forward, ShiftedWallScoreAbove(field, on_walls, -d, sigma, floor, &at));
  };
  double step = kPi / options.directions;
  double best_angle = 0.0;
  double best = shifted_above(0.0, -std::numeric_limits<double>::infinity());
  for (int i = 1; i < options.directions; ++i) {
    const double angle = i * step;
    const double score = shifted_above(angle, best);
    if (score > best) {
      best = score;
      best_angle = angle;
    }
  }
  // A ridge is narrow in angle (off its axis by a, a shift of reach moves the points
  // reach * sin(a) across the walls): halve the step around the best direction three times.
  for (int round = 0; round < 3; ++round) {
    step *= 0.5;
    const double candidates[] = {best_angle - step, best_angle + step};
    for (const double angle : candidates) {
      const double score = shifted_above(angle, best);
      if (score > best) {
        best = score;
        best_angle = angle;
      }
    }
  }
  FlatDirection flat;
  flat.axis = Eigen::Vector2d(std::cos(best_angle), std::sin(best_angle));
  flat.score_ratio = best / at_pose;
  return flat;
}

std::optional<FlatDirection> FindFlatDirection(const ScanReference& reference,
                                               const PointCloud& query, const Pose2& pose,
                                               const FlatDirectionOptions& options) {
  std::optional<FlatDirection> flat = MostFlatDirection(reference, query, pose, options);
  if (flat && flat->score_ratio < options.min_score_ratio) return std::nullopt;
  return flat;
}

}  // namespace anchormap
