#include "common/types/laser_scan.h"

#include <cmath>

namespace anchormap {

bool LaserScan::IsReturn(size_t i) const {
  const float r = ranges[i];
  return std::isfinite(r) && r > 0.0f && r < max_range;
}

std::vector<Eigen::Vector2d> LaserScan::PointsInBodyFrame() const {
  std::vector<Eigen::Vector2d> points;
  points.reserve(ranges.size());
  for (size_t i = 0; i < ranges.size(); ++i) {
    if (!IsReturn(i)) continue;
    const double a = Angle(i);
    points.push_back(
        T_body_sensor.TransformPoint({ranges[i] * std::cos(a), ranges[i] * std::sin(a)}));
  }
  return points;
}

}  // namespace anchormap
