#pragma once
// A scan as 2D points: the end points of its valid returns in the robot body frame (the
// scan's mounting pose T_body_sensor applied once, here), in beam order. Beam order matters to
// the reference field, which joins consecutive returns into wall segments.

#include <vector>

#include <Eigen/Core>

#include "common/geometry/pose2.h"
#include "common/types/laser_scan.h"

namespace anchormap {

using PointCloud = std::vector<Eigen::Vector2d>;

// Body-frame end points of the scan's returns no farther than `max_range_m` from the sensor
// (<= 0: every return).
PointCloud ScanToPointCloud(const LaserScan& scan, double max_range_m = 0.0);
// How many points ScanToPointCloud(scan, max_range_m) gives, without making them.
size_t CountScanPoints(const LaserScan& scan, double max_range_m = 0.0);

// Every point mapped by T_a_b (points given in frame b, result in frame a).
PointCloud TransformPointCloud(const PointCloud& cloud_b, const Pose2& T_a_b);

// Largest distance of a point from the origin (0 for an empty cloud).
double MaxPointRange(const PointCloud& cloud);

}  // namespace anchormap
