#include "tools/sim/simulated_laser.h"

#include <algorithm>
#include <cmath>

namespace anchormap::sim {

Status LaserOptions::Validate() const {
  if (beams < 2 || beams > 10000) return Status::Error("laser beams must be in [2, 10000]");
  if (!(fov_deg > 0.0 && fov_deg <= 360.0))
    return Status::Error("laser field of view must be in (0, 360] deg");
  if (!(max_range_m > 0.1 && max_range_m <= 1000.0))
    return Status::Error("laser max range must be in (0.1, 1000] m");
  if (!(range_noise_m >= 0.0 && range_noise_m < 1.0))
    return Status::Error("laser range noise must be in [0, 1) m");
  if (!(dropout_probability >= 0.0 && dropout_probability <= 1.0)) {
    return Status::Error("laser dropout probability must be in [0, 1]");
  }
  if (!(rate_hz > 0.0 && rate_hz <= 100.0))
    return Status::Error("laser rate must be in (0, 100] Hz");
  return Status::Ok();
}

double LaserOptions::radstep() const { return fov_deg * kPi / 180.0 / (beams - 1); }
double LaserOptions::rad0() const { return -0.5 * fov_deg * kPi / 180.0; }

LaserScan SimulatedLaser::Scan(const World& world, const Pose2& T_world_body, int64_t utime,
                               Rng& rng) const {
  LaserScan scan;
  scan.utime = utime;
  scan.rad0 = static_cast<float>(options_.rad0());
  scan.radstep = static_cast<float>(options_.radstep());
  scan.max_range = static_cast<float>(options_.max_range_m);
  scan.ranges.resize(options_.beams);
  const Eigen::Vector2d origin = T_world_body.translation();
  for (int i = 0; i < options_.beams; ++i) {
    // Draw noise and dropout for every beam so that the stream does not depend on hits.
    const double noise = rng.Gaussian() * options_.range_noise_m;
    const bool dropped = rng.Bernoulli(options_.dropout_probability);
    const double angle = T_world_body.theta() + options_.rad0() + i * options_.radstep();
    const double hit = world.RayCast(origin, angle, options_.max_range_m);
    float range = scan.max_range;
    if (hit != World::kNoHit && !dropped) {
      // Noise never turns a return into a "no return" (also not by rounding to float)
      // nor makes it negative.
      range =
          std::clamp(static_cast<float>(hit + noise), 0.0f, std::nextafter(scan.max_range, 0.0f));
    }
    scan.ranges[i] = range;
  }
  return scan;
}

}  // namespace anchormap::sim
