#include "tools/sim/sim_options.h"

#include <cmath>

namespace anchormap::sim {

Status SimOptions::Validate() const {
  if (robots < 1 || robots > 1000) return Status::Error("--robots must be in [1, 1000]");
  if (!(duration_s > 0.0 && duration_s <= 86400.0))
    return Status::Error("--duration-s must be in (0, 86400]");
  if (world.empty()) return Status::Error("--world must be 'office' or a .pgm / .yaml file");
  if (!(world_resolution_m > 0.0 && world_resolution_m <= 10.0)) {
    return Status::Error("--world-resolution-m must be in (0, 10]");
  }
  if (office_robots_per_tile < 1 || office_robots_per_tile > 100) {
    return Status::Error("--office-robots-per-tile must be in [1, 100]");
  }
  if (!(odometry_rate_hz > 0.0 && odometry_rate_hz <= 1000.0)) {
    return Status::Error("--odometry-rate-hz must be in (0, 1000]");
  }
  if (std::abs(1e6 / odometry_rate_hz - std::round(1e6 / odometry_rate_hz)) > 1e-6) {
    return Status::Error("--odometry-rate-hz must give a whole number of microseconds per step");
  }
  for (const Status& part : {laser.Validate(), odometry.Validate(), encounters.Validate(),
                             motion.Validate(), planner.Validate()}) {
    if (!part.ok()) return part;
  }
  const double ratio = odometry_rate_hz / laser.rate_hz;
  if (ratio < 1.0 - 1e-9 || std::abs(ratio - std::round(ratio)) > 1e-9) {
    return Status::Error("--odometry-rate-hz must be a whole multiple of --laser-rate-hz");
  }
  if (start_utime < 0) return Status::Error("start time must be >= 0");
  return Status::Ok();
}

int SimOptions::OdometryStepsPerScan() const {
  return static_cast<int>(std::lround(odometry_rate_hz / laser.rate_hz));
}

}  // namespace anchormap::sim
