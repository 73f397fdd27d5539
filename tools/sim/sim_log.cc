#include "tools/sim/sim_log.h"

#include <algorithm>
#include <cmath>

#include "common/bus/channels.h"
#include "common/bus/codec.h"
#include "common/bus/lcm_log.h"

namespace anchormap::sim {

bot_core::pose_t ToPoseMessage(int64_t utime, const Pose2& pose,
                               const Eigen::Vector3d& body_velocity) {
  bot_core::pose_t message{};
  message.utime = utime;
  message.pos[0] = pose.x();
  message.pos[1] = pose.y();
  message.pos[2] = 0.0;
  const Eigen::Vector2d velocity = pose.rotation() * body_velocity.head<2>();
  message.vel[0] = velocity.x();
  message.vel[1] = velocity.y();
  message.vel[2] = 0.0;
  message.orientation[0] = std::cos(0.5 * pose.theta());
  message.orientation[1] = 0.0;
  message.orientation[2] = 0.0;
  message.orientation[3] = std::sin(0.5 * pose.theta());
  message.rotation_rate[0] = 0.0;
  message.rotation_rate[1] = 0.0;
  message.rotation_rate[2] = body_velocity.z();
  std::fill(std::begin(message.accel), std::end(message.accel), 0.0);
  return message;
}

Pose2 FromPoseMessage(const bot_core::pose_t& message) {
  const double w = message.orientation[0];
  const double z = message.orientation[3];
  return Pose2(message.pos[0], message.pos[1], 2.0 * std::atan2(z, w));
}

anchormap::encounter_t ToEncounterMessage(const SimEncounter& encounter) {
  anchormap::encounter_t message;
  message.utime = encounter.utime;
  message.observer = RobotName(encounter.observer);
  message.observer_trajectory_id = 0;
  message.observed = RobotName(encounter.observed);
  message.relative_pose[0] = encounter.T_observer_observed.x();
  message.relative_pose[1] = encounter.T_observer_observed.y();
  message.relative_pose[2] = encounter.T_observer_observed.theta();
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) message.covariance[3 * r + c] = encounter.covariance(r, c);
  }
  return message;
}

Status WriteSimulationLog(const SimOptions& options, const std::string& path, SimSummary* summary,
                          SimTrace* trace) {
  std::unique_ptr<Simulator> simulator;
  if (Status status = Simulator::Create(options, &simulator); !status.ok()) return status;
  LcmLogWriter writer;
  if (Status status = writer.Open(path); !status.ok()) return status;

  SimSummary result;
  result.robots = simulator->num_robots();
  result.world_min = simulator->world().min_corner();
  result.world_max = simulator->world().max_corner();
  std::vector<std::string> odometry_channels, laser_channels, truth_channels, encounter_channels;
  for (int i = 0; i < simulator->num_robots(); ++i) {
    const std::string& name = simulator->robot(i).name();
    odometry_channels.push_back(channels::Odometry(name));
    laser_channels.push_back(channels::Laser(name));
    truth_channels.push_back(channels::GroundTruth(name));
    encounter_channels.push_back(channels::Encounter(name));
  }
  if (trace)
    *trace = SimTrace{std::vector<std::vector<Eigen::Vector2d>>(simulator->num_robots()), {}};
  auto write = [&](const std::string& channel, int64_t utime, const auto& message) {
    ++result.events;
    return writer.Write(channel, utime, message);
  };
  auto write_encoded = [&](const std::string& channel, int64_t utime,
                           const std::vector<uint8_t>& bytes) {
    ++result.events;
    return writer.WriteRaw(channel, utime, bytes.data(), bytes.size());
  };

  while (!simulator->Done()) {
    const SimFrame frame = simulator->Step();
    // Per step: every robot's odometry, then (laser steps) every robot's scan and ground
    // truth, then the encounters. Odometry first, so an agent has it at the scan's time.
    for (int i = 0; i < simulator->num_robots(); ++i) {
      const SimRobot& robot = simulator->robot(i);
      Status status = write(odometry_channels[i], frame.utime,
                            ToPoseMessage(frame.utime, robot.T_odom_body(), robot.body_velocity()));
      if (!status.ok()) return status;
    }
    if (!frame.has_scans) continue;
    for (int i = 0; i < simulator->num_robots(); ++i) {
      const SimRobot& robot = simulator->robot(i);
      Status status = write_encoded(laser_channels[i], frame.utime, EncodeLaser(frame.scans[i]));
      if (status.ok()) {
        status = write(truth_channels[i], frame.utime,
                       ToPoseMessage(frame.utime, robot.T_world_body(), robot.body_velocity()));
      }
      if (!status.ok()) return status;
      ++result.scans;
      if (trace) trace->paths[i].push_back(robot.T_world_body().translation());
    }
    for (const SimEncounter& encounter : frame.encounters) {
      Status status =
          write(encounter_channels[encounter.observer], frame.utime, ToEncounterMessage(encounter));
      if (!status.ok()) return status;
      ++result.encounters;
      if (trace) {
        trace->encounters.emplace_back(
            simulator->robot(encounter.observer).T_world_body().translation(),
            simulator->robot(encounter.observed).T_world_body().translation());
      }
      ++result.encounters_by_pair[{std::min(encounter.observer, encounter.observed),
                                   std::max(encounter.observer, encounter.observed)}];
    }
  }
  writer.Close();
  for (int i = 0; i < simulator->num_robots(); ++i) {
    result.distance_m.push_back(simulator->robot(i).distance_m());
    result.planning_failures += simulator->robot(i).planning_failures();
  }
  if (summary) *summary = std::move(result);
  return Status::Ok();
}

}  // namespace anchormap::sim
