#pragma once
// Test scenarios for the server's scan matching: floor plans with a loop to close (and one
// whose two corridors look alike), paths around them, and the keyframes a robot driving a
// path would send (noisy odometry deltas with their covariance, simulated scans).
// Deterministic for a given seed.

#include <cstdint>
#include <string>
#include <vector>

#include "common/geometry/pose2.h"
#include "common/types/keyframe.h"
#include "tests/scan_testing/synthetic_world.h"

namespace anchormap::testing {

// A 23 m x 16 m room around a 10 m x 6 m block: a corridor loop 4-8 m wide, with
// pillars and alcoves of different sizes along the walls so that no two places look alike.
SyntheticWorld LoopWorld();

// Two parallel corridors, 3 m wide and 16 m long, that look exactly alike (the second is
// the first moved by (0, 10) m), joined at their west ends by a hall with distinct pillars.
SyntheticWorld TwinCorridorWorld();

// A corridor ring around a 54 m x 7 m block (corridors 3 m wide) whose south corridor repeats
// every 8 m: door jambs at x = 8k on its south wall and 8k + 3 on its north wall, as the
// simulator's offices repeat their rooms. A place there looks like the places 8 m away.
SyntheticWorld PeriodicCorridorWorld();

// A 30 m x 8 m hall that looks the same turned by 180 degrees about its middle (15, 4) (its
// features in turned pairs, a door at the west end of the north wall and at the east end of
// the south wall), as the simulator's offices have such rooms; its surroundings do not: the
// north door opens into a corridor running north, the south one into a corridor running east.
SyntheticWorld TurnedHallWorld();

// Poses every `step_m` along the rectangle [lo, hi] driven counter-clockwise from `lo`,
// heading along the side (turning at corners in one step), for `laps` laps (fractions
// allowed).
std::vector<Pose2> RectanglePath(const Eigen::Vector2d& lo, const Eigen::Vector2d& hi,
                                 double step_m, double laps);

// `count` poses of two counter-clockwise laps around LoopWorld's block at 0.5 m steps, from
// pose `first` (0: the south-west corner; 50: near the north-east one). Two robots given
// different `first` lap the block from opposite corners.
std::vector<Pose2> LoopWorldLap(size_t first, size_t count);

// Poses every `step_m` from `from` to `to` (heading along the segment).
std::vector<Pose2> StraightPath(const Eigen::Vector2d& from, const Eigen::Vector2d& to,
                                double step_m);

struct OdometryNoise {
  double sigma_xy_m = 0.02;       // per step
  double sigma_theta_rad = 0.01;  // per step
  // Added to every step's turn and not in the covariance (a miscalibrated odometry): drift
  // the estimate does not know of, as scan-matched odometry on real logs has.
  double bias_theta_rad = 0.0;
};

// The keyframes robot `robot` sends driving `path` (world poses), one per pose, 0.5 s
// apart from `start_utime`: odometry starts at the identity, deltas are the true ones plus
// noise, the covariance is the noise's; each carries a simulated 360-beam scan.
std::vector<Keyframe> DriveKeyframes(const SyntheticWorld& world, const std::vector<Pose2>& path,
                                     const std::string& robot, int64_t trajectory_id,
                                     int64_t start_utime, const OdometryNoise& noise,
                                     uint64_t seed);

}  // namespace anchormap::testing
