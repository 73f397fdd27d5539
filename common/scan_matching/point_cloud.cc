#include "common/scan_matching/point_cloud.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <vector>

namespace anchormap {

namespace {
// The beams both functions below keep: returns no farther than max_range_m (<= 0: all).
bool KeepsBeam(const LaserScan& scan, size_t i, double max_range_m) {
  return scan.IsReturn(i) && !(max_range_m > 0.0 && scan.ranges[i] > max_range_m);
}
}  // namespace

PointCloud ScanToPointCloud(const LaserScan& scan, double max_range_m) {
  // The beams' cosines and sines of the last scan geometry this thread saw (a team's scans
  // share one): the same std::cos / std::sin of the same angles, computed once instead of per
  // scan (each reference build converts every keyframe of its submap again). With the
  // sensor's rotation taken once, the points are those of T_body_sensor.TransformPoint.
  struct Directions {
    double rad0 = std::numeric_limits<double>::quiet_NaN();
    double radstep = std::numeric_limits<double>::quiet_NaN();
    std::vector<double> cos, sin;
  };
  thread_local Directions directions;
  const size_t n = scan.ranges.size();
  if (!(directions.rad0 == scan.rad0 && directions.radstep == scan.radstep &&
        directions.cos.size() >= n)) {
    directions.rad0 = scan.rad0;
    directions.radstep = scan.radstep;
    directions.cos.resize(n);
    directions.sin.resize(n);
    for (size_t i = 0; i < n; ++i) {
      const double a = scan.Angle(i);
      directions.cos[i] = std::cos(a);
      directions.sin[i] = std::sin(a);
    }
  }
  const Eigen::Matrix2d rotation = scan.T_body_sensor.rotation();
  const Eigen::Vector2d translation = scan.T_body_sensor.translation();
  PointCloud cloud;
  cloud.reserve(n);
  for (size_t i = 0; i < n; ++i) {
    if (!KeepsBeam(scan, i, max_range_m)) continue;
    const double r = scan.ranges[i];
    const Eigen::Vector2d point(r * directions.cos[i], r * directions.sin[i]);
    cloud.push_back(rotation * point + translation);
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
