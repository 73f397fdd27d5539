#include "common/scan_matching/point_cloud.h"

#include <algorithm>
#include <cmath>

namespace anchormap {

PointCloud ScanToPointCloud(const LaserScan& scan, double max_range_m) {
  PointCloud cloud;
  cloud.reserve(scan.ranges.size());
  for (size_t i = 0; i < scan.ranges.size(); ++i) {
    if (!scan.IsReturn(i)) continue;
    const double r = scan.ranges[i];
    if (max_range_m > 0.0 && r > max_range_m) continue;
    const double a = scan.Angle(i);
    cloud.push_back(scan.T_body_sensor.TransformPoint({r * std::cos(a), r * std::sin(a)}));
  }
  return cloud;
}

PointCloud TransformPointCloud(const PointCloud& cloud_b, const Pose2& T_a_b) {
  PointCloud out;
  out.reserve(cloud_b.size());
  const Eigen::Matrix2d R = T_a_b.rotation();
  const Eigen::Vector2d t = T_a_b.translation();
  for (const Eigen::Vector2d& p : cloud_b) out.push_back(R * p + t);
  return out;
}

double MaxPointRange(const PointCloud& cloud) {
  double r = 0.0;
  for (const Eigen::Vector2d& p : cloud) r = std::max(r, p.norm());
  return r;
}

}  // namespace anchormap
