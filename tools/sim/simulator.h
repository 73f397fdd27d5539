#pragma once
// The multi-robot simulation as a sequence of frames, one per odometry step: world,
// robots, laser scans (every OdometryStepsPerScan() steps), ground truth and direct
// encounters. Plain values only: sim_log.h turns frames into LCM messages.

#include <cstdint>
#include <memory>
#include <vector>

#include "common/types/laser_scan.h"
#include "common/util/status.h"
#include "tools/sim/destinations.h"
#include "tools/sim/encounter_detector.h"
#include "tools/sim/floor_plan.h"
#include "tools/sim/robot_sim.h"
#include "tools/sim/route_planner.h"
#include "tools/sim/sim_options.h"
#include "tools/sim/simulated_laser.h"
#include "tools/sim/world.h"

namespace anchormap::sim {

struct SimFrame {
  int64_t utime = 0;
  bool has_scans = false;                // a laser step: scans and ground truth are filled
  std::vector<LaserScan> scans;          // one per robot (laser steps only)
  std::vector<SimEncounter> encounters;  // laser steps only
};

class Simulator {
 public:
  // Builds the world (office or PGM), the planner and the robots; fails on a bad world file
  // or a world without room for the robots. `options` must be valid.
  static Status Create(const SimOptions& options, std::unique_ptr<Simulator>* simulator);

  // The first frame is at the start time with every robot at its start; Done() after
  // duration_s.
  bool Done() const { return next_step_ > last_step_; }
  SimFrame Step();

  int num_robots() const { return static_cast<int>(robots_.size()); }
  const SimRobot& robot(int index) const { return robots_[index]; }
  const World& world() const { return *world_; }
  const FloorPlan& floor_plan() const { return plan_; }
  const RoutePlanner& planner() const { return *planner_; }

 private:
  explicit Simulator(const SimOptions& options) : options_(options) {}

  SimOptions options_;
  FloorPlan plan_;
  std::unique_ptr<World> world_;
  std::unique_ptr<RoutePlanner> planner_;
  std::unique_ptr<Destinations> destinations_;
  std::unique_ptr<EncounterDetector> detector_;
  SimulatedLaser laser_{LaserOptions{}};
  std::vector<SimRobot> robots_;
  std::vector<Rng> laser_rngs_;
  std::vector<Rng> encounter_rngs_;
  int64_t step_us_ = 0;
  int64_t next_step_ = 0;
  int64_t last_step_ = 0;
};

}  // namespace anchormap::sim
