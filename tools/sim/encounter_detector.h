#pragma once
// Direct encounters: robot A "sees" robot B (a fiducial or robot detector) when B is
// within range, inside A's detector field of view and in line of sight (no wall between
// their centres). A reports B's body pose in A's body frame, with Gaussian noise of a
// known diagonal covariance, at most once per period for each ordered pair.

#include <cstdint>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "common/geometry/pose2.h"
#include "common/util/status.h"
#include "tools/sim/random.h"
#include "tools/sim/world.h"

namespace anchormap::sim {

struct EncounterOptions {
  double max_range_m = 5.0;          // farthest detection
  double field_of_view_deg = 360.0;  // detector field of view, centred on the heading
  double min_period_s = 2.0;         // at most one encounter per ordered pair per period
  double sigma_xy_m = 0.05;          // noise of the measured relative position
  double sigma_theta_rad = 0.02;     // noise of the measured relative heading

  Status Validate() const;  // empty when valid
};

struct SimEncounter {
  int64_t utime = 0;
  int observer = 0;  // robot indices
  int observed = 0;
  Pose2 T_observer_observed;       // measured (noisy)
  Pose2 T_observer_observed_true;  // for tests and diagnostics
  Eigen::Matrix3d covariance = Eigen::Matrix3d::Identity();
};

class EncounterDetector {
 public:
  EncounterDetector(const EncounterOptions& options, int num_robots);

  // Encounters at `utime` between the robots at `T_world_body` (one per robot); noise is
  // drawn from the observer's stream `rngs[observer]`. Ordered by observer, then observed.
  std::vector<SimEncounter> Detect(int64_t utime, const World& world,
                                   const std::vector<Pose2>& T_world_body, std::vector<Rng>& rngs);

 private:
  EncounterOptions options_;
  int num_robots_;
  std::vector<int64_t> last_utime_;  // per ordered pair; INT64_MIN = never
};

}  // namespace anchormap::sim
