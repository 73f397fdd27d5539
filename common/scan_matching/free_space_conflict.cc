#include "common/scan_matching/free_space_conflict.h"

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <limits>

namespace anchormap {
namespace {

int64_t CellIndex(double x, double resolution) {
  return static_cast<int64_t>(std::floor(x / resolution));
}

}  // namespace

FreeSpaceMap::FreeSpaceMap(const std::vector<RayScan>& scans, const FreeSpaceOptions& options)
    : options_(options) {
  Eigen::Vector2d low = Eigen::Vector2d::Constant(std::numeric_limits<double>::infinity());
  Eigen::Vector2d high = -low;
  for (const RayScan& scan : scans) {
    low = low.cwiseMin(scan.origin);
    high = high.cwiseMax(scan.origin);
    for (const Eigen::Vector2d& p : scan.end_points) {
      low = low.cwiseMin(p);
      high = high.cwiseMax(p);
    }
  }
  if (scans.empty()) return;
  const double r = options_.resolution_m;
  const int64_t pad = static_cast<int64_t>(std::ceil(options_.wall_margin_m / r)) + 1;
  min_i_ = CellIndex(low.x(), r) - pad;
  min_j_ = CellIndex(low.y(), r) - pad;
  width_ = CellIndex(high.x(), r) + pad - min_i_ + 1;
  height_ = CellIndex(high.y(), r) + pad - min_j_ + 1;
  cells_.assign(static_cast<size_t>(width_ * height_), 0);

  const double margin = options_.wall_margin_m;
  // (centre - p).norm() <= margin decided without the square root away from the margin's
  // circle: the root's rounding is ~1e-16 relative, far inside these bounds.
  const double surely_within_sq = margin * margin * (1.0 - 1e-9);
  const double surely_beyond_sq = margin * margin * (1.0 + 1e-9);
  for (const RayScan& scan : scans) {
    for (const Eigen::Vector2d& p : scan.end_points) {
      const Eigen::Vector2d ray = p - scan.origin;
      const double length = ray.norm();
      if (length > margin) MarkRay(scan.origin, p - ray * (margin / length));
      // Cells whose centre lies within the margin of the end point.
      for (int64_t i = CellIndex(p.x() - margin, r) - 1; i <= CellIndex(p.x() + margin, r) + 1;
           ++i) {
        for (int64_t j = CellIndex(p.y() - margin, r) - 1; j <= CellIndex(p.y() + margin, r) + 1;
             ++j) {
          const Eigen::Vector2d centre((static_cast<double>(i) + 0.5) * r,
                                       (static_cast<double>(j) + 0.5) * r);
          const double sq = (centre - p).squaredNorm();
          if (sq <= surely_within_sq || (sq <= surely_beyond_sq && std::sqrt(sq) <= margin)) {
            Mark(i, j, kWall);
          }
        }
      }
    }
  }
}

void FreeSpaceMap::Mark(int64_t i, int64_t j, uint8_t flag) {
  const int64_t x = i - min_i_;
  const int64_t y = j - min_j_;
  if (x < 0 || y < 0 || x >= width_ || y >= height_) return;
  cells_[static_cast<size_t>(y * width_ + x)] |= flag;
}

// Every cell the segment touches, in order (Amanatides and Woo): one step in x or in y per
// cell boundary crossed, as many steps as the end cell lies away in x and y together.
void FreeSpaceMap::MarkRay(const Eigen::Vector2d& from, const Eigen::Vector2d& to) {
  const double r = options_.resolution_m;
  int64_t i = CellIndex(from.x(), r);
  int64_t j = CellIndex(from.y(), r);
  const int64_t end_i = CellIndex(to.x(), r);
  const int64_t end_j = CellIndex(to.y(), r);
  const Eigen::Vector2d d = to - from;
  const int64_t step_i = d.x() > 0 ? 1 : -1;
  const int64_t step_j = d.y() > 0 ? 1 : -1;
  const double inf = std::numeric_limits<double>::infinity();
  // Ray parameter t in [0, 1] at the next x (y) boundary, and between boundaries.
  double next_x =
      d.x() == 0.0 ? inf : ((static_cast<double>(i + (d.x() > 0 ? 1 : 0)) * r) - from.x()) / d.x();
  double next_y =
      d.y() == 0.0 ? inf : ((static_cast<double>(j + (d.y() > 0 ? 1 : 0)) * r) - from.y()) / d.y();
  const double delta_x = d.x() == 0.0 ? inf : r / std::abs(d.x());
  const double delta_y = d.y() == 0.0 ? inf : r / std::abs(d.y());
  int64_t steps = std::abs(end_i - i) + std::abs(end_j - j);
  Mark(i, j, kFree);
  while (steps-- > 0) {
    if (next_x < next_y) {
      i += step_i;
      next_x += delta_x;
    } else {
      j += step_j;
      next_y += delta_y;
    }
    Mark(i, j, kFree);
  }
}

uint8_t FreeSpaceMap::CellAt(const Eigen::Vector2d& point) const {
  const int64_t x = CellIndex(point.x(), options_.resolution_m) - min_i_;
  const int64_t y = CellIndex(point.y(), options_.resolution_m) - min_j_;
  if (x < 0 || y < 0 || x >= width_ || y >= height_) return 0;
  return cells_[static_cast<size_t>(y * width_ + x)];
}

bool FreeSpaceMap::Contradicts(const Eigen::Vector2d& point) const {
  return CellAt(point) == kFree;
}

bool FreeSpaceMap::Seen(const Eigen::Vector2d& point) const { return CellAt(point) != 0; }

FreeSpaceConflict CountFreeSpaceConflicts(const FreeSpaceMap& map,
                                          const std::vector<RayScan>& scans) {
  FreeSpaceConflict conflict;
  for (const RayScan& scan : scans) {
    for (const Eigen::Vector2d& p : scan.end_points) {
      if (!map.Seen(p)) continue;
      ++conflict.seen;
      if (map.Contradicts(p)) ++conflict.contradicts;
    }
  }
  return conflict;
}

}  // namespace anchormap
