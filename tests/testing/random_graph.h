#pragma once
// Seeded random single-trajectory pose graphs with loop closures, and their ground truth.

#include <cstdint>

#include "common/io/graph_file.h"

namespace anchormap::testing {

struct RandomGraphOptions {
  int poses = 100;
  int loop_closures = 20;  // between random earlier poses within max_loop_distance_m
  double max_loop_distance_m = 3.0;
  double arena_radius_m = 10.0;  // the walk turns home beyond this distance from its start
  double sigma_xy_m = 0.05;      // measurement noise
  double sigma_theta_rad = 0.02;
  uint32_t seed = 1;
};

// Vertices hold the ground truth; edges are noisy measurements: odometry (i, i+1) and
// loop closures (i, j), i < j.
PoseGraph RandomGraph(const RandomGraphOptions& options);

}  // namespace anchormap::testing
