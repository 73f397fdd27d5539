#pragma once
// Runs a simulation and writes it as an LCM log (the format of lcm-logger, replayable by
// lcm-logplayer): per robot R, R_ODOMETRY (bot_core.pose_t, odometry frame), R_LASER
// (bot_core.planar_lidar_t), R_GROUND_TRUTH (bot_core.pose_t, world frame, at the laser's
// times) and R_ENCOUNTER (anchormap.encounter_t). Event times equal message times.

#include <cstdint>
#include <map>
#include <string>
#include <utility>
#include <vector>

#include "anchormap/encounter_t.hpp"
#include "bot_core/pose_t.hpp"
#include "common/util/status.h"
#include "tools/sim/sim_preview.h"
#include "tools/sim/simulator.h"

namespace anchormap::sim {

struct SimSummary {
  int robots = 0;
  int64_t events = 0;
  int64_t scans = 0;
  int64_t encounters = 0;
  std::map<std::pair<int, int>, int> encounters_by_pair;  // (lower, higher robot index)
  std::vector<double> distance_m;                         // driven per robot
  int planning_failures = 0;
  Eigen::Vector2d world_min{0.0, 0.0};
  Eigen::Vector2d world_max{0.0, 0.0};
};

// Runs the simulation of `options` and writes it to `path`. `summary` and `trace` (the
// ground truth for sim_preview.h) are optional.
Status WriteSimulationLog(const SimOptions& options, const std::string& path, SimSummary* summary,
                          SimTrace* trace = nullptr);

// Message conversions (also used by tests; scans are encoded by common/bus/codec's
// EncodeLaser). Velocities are body-frame (forward, lateral, yaw rate) and are rotated
// into the pose's frame for pose_t.vel.
bot_core::pose_t ToPoseMessage(int64_t utime, const Pose2& pose,
                               const Eigen::Vector3d& body_velocity = Eigen::Vector3d::Zero());
anchormap::encounter_t ToEncounterMessage(const SimEncounter& encounter);

// Reads the pose back (x, y, yaw from the quaternion).
Pose2 FromPoseMessage(const bot_core::pose_t& message);

}  // namespace anchormap::sim
