#include "tools/sim/encounter_detector.h"

#include <cmath>
#include <limits>

namespace anchormap::sim {

Status EncounterOptions::Validate() const {
  if (!(max_range_m > 0.0 && max_range_m <= 100.0))
    return Status::Error("encounter range must be in (0, 100] m");
  if (!(field_of_view_deg > 0.0 && field_of_view_deg <= 360.0)) {
    return Status::Error("encounter field of view must be in (0, 360] deg");
  }
  if (!(min_period_s >= 0.0 && min_period_s <= 3600.0))
    return Status::Error("encounter period must be in [0, 3600] s");
  if (!(sigma_xy_m > 0.0 && sigma_xy_m < 10.0))
    return Status::Error("encounter sigma xy must be in (0, 10) m");
  if (!(sigma_theta_rad > 0.0 && sigma_theta_rad < 1.0))
    return Status::Error("encounter sigma theta must be in (0, 1) rad");
  return Status::Ok();
}

EncounterDetector::EncounterDetector(const EncounterOptions& options, int num_robots)
    : options_(options),
      num_robots_(num_robots),
      last_utime_(static_cast<size_t>(num_robots) * num_robots,
                  std::numeric_limits<int64_t>::min()) {}

std::vector<SimEncounter> EncounterDetector::Detect(int64_t utime, const World& world,
                                                    const std::vector<Pose2>& T_world_body,
                                                    std::vector<Rng>& rngs) {
  std::vector<SimEncounter> encounters;
  const double half_fov = 0.5 * options_.field_of_view_deg * kPi / 180.0;
  const int64_t period_us = static_cast<int64_t>(std::llround(options_.min_period_s * 1e6));
  const double max_range_sq = options_.max_range_m * options_.max_range_m;
  for (int a = 0; a < num_robots_; ++a) {
    for (int b = 0; b < num_robots_; ++b) {
      if (a == b) continue;
      int64_t& last = last_utime_[static_cast<size_t>(a) * num_robots_ + b];
      if (last != std::numeric_limits<int64_t>::min() && utime - last < period_us) continue;
      const Eigen::Vector2d delta = T_world_body[b].translation() - T_world_body[a].translation();
      if (delta.squaredNorm() > max_range_sq) continue;
      const Pose2 T_a_b = Between(T_world_body[a], T_world_body[b]);
      if (std::abs(std::atan2(T_a_b.y(), T_a_b.x())) > half_fov + 1e-12) continue;
      if (!world.LineOfSight(T_world_body[a].translation(), T_world_body[b].translation()))
        continue;
      last = utime;
      SimEncounter encounter;
      encounter.utime = utime;
      encounter.observer = a;
      encounter.observed = b;
      encounter.T_observer_observed_true = T_a_b;
      Rng& rng = rngs[a];
      const double nx = rng.Gaussian() * options_.sigma_xy_m;
      const double ny = rng.Gaussian() * options_.sigma_xy_m;
      const double nt = rng.Gaussian() * options_.sigma_theta_rad;
      encounter.T_observer_observed = Pose2(T_a_b.x() + nx, T_a_b.y() + ny, T_a_b.theta() + nt);
      encounter.covariance = Eigen::Vector3d(options_.sigma_xy_m * options_.sigma_xy_m,
                                             options_.sigma_xy_m * options_.sigma_xy_m,
                                             options_.sigma_theta_rad * options_.sigma_theta_rad)
                                 .asDiagonal();
      encounters.push_back(encounter);
    }
  }
  return encounters;
}

}  // namespace anchormap::sim
