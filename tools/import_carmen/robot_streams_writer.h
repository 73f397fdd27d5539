#pragma once
// Writes the importer's robot streams into an LCM log of bot_core messages, in time order:
// <R>_ODOMETRY (bot_core.pose_t), <R>_LASER (bot_core.planar_lidar_t) and <R>_REFERENCE
// (bot_core.pose_t), channel names from patterns in which "{robot}" stands for the name; before a
// robot's first measurement its laser's mounting pose on <laser channel>_MOUNT (pose_t) and,
// when pieces were shifted in time, its shift on <R>_CLOCK_SHIFT (common/bus/channels.h).

#include <cstdint>
#include <string>
#include <vector>

#include "bot_core/planar_lidar_t.hpp"
#include "bot_core/pose_t.hpp"
#include "common/bus/channels.h"
#include "common/util/status.h"
#include "tools/import_carmen/robot_streams.h"

namespace anchormap {

struct ImportChannels {
  std::string odometry = std::string("{robot}") + channels::kOdometrySuffix;
  std::string laser = std::string("{robot}") + channels::kLaserSuffix;
  std::string reference = std::string("{robot}") + channels::kReferenceSuffix;

  // Each pattern must contain "{robot}" and give an upper-case channel name.
  Status Validate() const;
};

// `pattern` with every "{robot}" replaced by `robot`.
std::string ChannelName(const std::string& pattern, const std::string& robot);

// bot_core.pose_t of a planar pose: pos = (x, y, 0), orientation = (cos(theta/2), 0, 0,
// sin(theta/2)); vel = tv along the heading, in the pose's frame (libbot2: "velocity in the
// local frame, not the body frame"); rotation_rate = (0, 0, rv); accel zero.
bot_core::pose_t ToPoseMessage(int64_t utime, const Pose2& pose, double tv_mps = 0.0,
                               double rv_radps = 0.0);

bot_core::planar_lidar_t ToLidarMessage(const RobotScan& scan);

struct WriteCounts {
  int64_t odometry = 0;
  int64_t scans = 0;
  int64_t reference = 0;
  int64_t laser_mounts = 0;
  int64_t clock_shifts = 0;
  int64_t time_repairs = 0;
};

// Writes all robots' messages to `path` (truncated), merged in time order; at equal times
// odometry comes before scans and scans before reference poses, robots in the given order.
Status WriteRobotStreams(const std::vector<RobotStream>& robots, const ImportChannels& channels,
                         const std::string& path, WriteCounts* counts);

}  // namespace anchormap
