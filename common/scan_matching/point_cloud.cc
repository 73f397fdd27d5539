#include "common/scan_matching/point_cloud.h"

#include <algorithm>
#include <cmath>

namespace anchormap {

namespace {
// The beams both functions below keep: returns no farther than max_range_m (<= 0: all).
bool KeepsBeam(const LaserScan& scan, size_t i, double max_range_m) {
  return scan.IsReturn(i) && !(max_range_m > 0.0 && scan.ranges[i] > max_range_m);
}
}  // namespace

PointCloud ScanToPointCloud(const LaserScan& scan, double max_range_m) {
  PointCloud cloud;
  cloud.reserve(scan.ranges.size());
  for (size_t i = 0; i < scan.ranges.size(); ++i) {
    if (!KeepsBeam(scan, i, max_range_m)) continue;
    const double r = scan.ranges[i];
    const double a = scan.Angle(i);
    cloud.push_back(scan.T_body_sensor.TransformPoint({r * std::cos(a), r * std::sin(a)}));
  }
  return cloud;
}

size_t CountScanPoints(const LaserScan& scan, double max_range_m) {
  size_t count = 0;
  for (size_t i = 0; i < scan.ranges.size(); ++i) count += KeepsBeam(scan, i, max_range_m);
  return count;
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
