#pragma once
// Every option of anchormap-sim in one tree, with its defaults (the single source of the
// defaults: sim_main's flags and docs/TOOLS-SIM.md are written from these fields).

#include <cstdint>
#include <string>

#include "common/util/status.h"
#include "tools/sim/encounter_detector.h"
#include "tools/sim/odometry_model.h"
#include "tools/sim/route_follower.h"
#include "tools/sim/route_planner.h"
#include "tools/sim/simulated_laser.h"

namespace anchormap::sim {

// Message times start here (2023-11-14 22:13:20 UTC), so equal seeds give equal logs.
constexpr int64_t kSimEpochUtime = 1700000000000000;

struct SimOptions {
  int robots = 3;                    // robots R1 .. RN, 1 to 1000
  uint64_t seed = 1;                 // everything random derives from it
  double duration_s = 180.0;         // simulated time
  std::string world = "office";      // "office" or a .pgm / map_server .yaml file
  double world_resolution_m = 0.05;  // metres per pixel of a .pgm world
  int office_robots_per_tile = 6;    // the office grows by 40 x 30 m tiles beyond this
  double odometry_rate_hz = 50.0;    // odometry messages per second; a multiple of the laser rate
  int64_t start_utime = kSimEpochUtime;

  LaserOptions laser;
  OdometryNoiseOptions odometry;
  EncounterOptions encounters;
  MotionOptions motion;
  RoutePlannerOptions planner;

  Status Validate() const;  // empty when valid, else the first problem found
  // Odometry steps per laser scan (odometry_rate_hz / laser.rate_hz).
  int OdometryStepsPerScan() const;
};

}  // namespace anchormap::sim
