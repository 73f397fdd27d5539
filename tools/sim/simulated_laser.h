#pragma once
// A planar laser mounted at the robot's body origin: one exact ray cast per beam, plus
// Gaussian range noise, and "no return" readings (reported as the maximum range) where
// nothing is hit within range or a beam randomly drops out.

#include <cstdint>
#include <string>

#include "common/geometry/pose2.h"
#include "common/types/laser_scan.h"
#include "common/util/status.h"
#include "tools/sim/random.h"
#include "tools/sim/world.h"

namespace anchormap::sim {

struct LaserOptions {
  int beams = 361;                   // rays per scan, first at -fov/2, last at +fov/2
  double fov_deg = 360.0;            // field of view, centred on the robot's heading
  double max_range_m = 30.0;         // no-return readings are published as this value
  double range_noise_m = 0.01;       // standard deviation of the range noise
  double dropout_probability = 0.0;  // chance that a beam returns nothing although it hits
  double rate_hz = 10.0;             // scans per second

  Status Validate() const;  // empty when valid
  double radstep() const;   // angle between beams
  double rad0() const;      // angle of the first beam
};

class SimulatedLaser {
 public:
  explicit SimulatedLaser(const LaserOptions& options) : options_(options) {}

  // One scan from the robot at `T_world_body`. With zero noise and no dropout every
  // range is the exact distance to the first wall (as a float).
  LaserScan Scan(const World& world, const Pose2& T_world_body, int64_t utime, Rng& rng) const;

 private:
  LaserOptions options_;
};

}  // namespace anchormap::sim
