#pragma once
// Keyframes of a simulated team for the component benches (the occupancy grid, the scan
// references): the scans and true poses the simulator's robots give, without agents or a
// server.

#include <cstdint>
#include <vector>

#include "common/geometry/pose2.h"
#include "common/types/laser_scan.h"
#include "common/util/status.h"
#include "tools/sim/sim_options.h"

namespace anchormap {

struct SimulatedKeyframe {
  int robot = 0;
  LaserScan scan;
  Pose2 T_world_body;   // the truth
  double time_s = 0.0;  // since the simulation's start
};

// Runs the simulation of `options` to its end and keeps each robot's scan and true pose at
// most once every `keyframe_period_s` of simulated time, in time order (robots in their
// order within a laser step). Fails on invalid options or a world without room.
Status SimulateKeyframes(const sim::SimOptions& options, double keyframe_period_s,
                         std::vector<SimulatedKeyframe>* keyframes);

// FNV-1a over 64-bit words: the benches' hash of what they built (the same inputs must give
// the same hash whatever the implementation).
struct Fnv1aHash {
  uint64_t value = 1469598103934665603ull;
  void Mix(uint64_t v) {
    value ^= v;
    value *= 1099511628211ull;
  }
};

}  // namespace anchormap
