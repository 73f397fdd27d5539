#pragma once
// A planar laser scan as a plain value (no LCM): what the agent puts into a keyframe and
// what the occupancy grid and scan matchers consume.

#include <cstdint>
#include <vector>

#include <Eigen/Core>

#include "common/geometry/pose2.h"

namespace anchormap {

struct LaserScan {
  int64_t utime = 0;
  float rad0 = 0.0f;       // angle of ranges[0] in the sensor frame, radians
  float radstep = 0.0f;    // angle between consecutive ranges, radians
  float max_range = 0.0f;  // a range >= max_range (or <= 0, or not finite) is "no return"
  std::vector<float> ranges;
  Pose2 T_body_sensor;  // the sensor's mounting pose on the robot

  bool IsReturn(size_t i) const;
  double Angle(size_t i) const { return rad0 + static_cast<double>(i) * radstep; }
  // End points of the valid returns in the robot body frame.
  std::vector<Eigen::Vector2d> PointsInBodyFrame() const;
};

}  // namespace anchormap
