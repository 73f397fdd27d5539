#include "tools/import_carmen/robot_streams_writer.h"

#include <algorithm>
#include <cmath>

#include "common/bus/lcm_log.h"

namespace anchormap {
namespace {

constexpr const char* kRobotToken = "{robot}";

Status ValidatePattern(const char* name, const std::string& pattern) {
  if (pattern.find(kRobotToken) == std::string::npos) {
    return Status::Error(std::string(name) + " channel pattern '" + pattern +
                         "' does not contain {robot}");
  }
  const std::string example = ChannelName(pattern, "R1");
  for (char c : example) {
    if (!((c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') || c == '_')) {
      return Status::Error(std::string(name) + " channel pattern '" + pattern +
                           "' does not give an upper-case channel name");
    }
  }
  return Status::Ok();
}

// At equal times, in this order: a robot's parameters come before its first measurements.
enum class Kind {
  kLaserMount = 0,
  kClockShift = 1,
  kOdometry = 2,
  kScan = 3,
  kReference = 4,
  kTimeRepair = 5
};

int64_t FirstUtime(const RobotStream& robot) {
  int64_t first = robot.odometry.empty() ? 0 : robot.odometry.front().utime;
  if (!robot.scans.empty() && (robot.odometry.empty() || robot.scans.front().utime < first)) {
    first = robot.scans.front().utime;
  }
  return first;
}

struct Event {
  int64_t utime;
  Kind kind;
  size_t robot;
  size_t index;
};

}  // namespace

Status ImportChannels::Validate() const {
  if (Status s = ValidatePattern("odometry", odometry); !s.ok()) return s;
  if (Status s = ValidatePattern("laser", laser); !s.ok()) return s;
  return ValidatePattern("reference", reference);
}

std::string ChannelName(const std::string& pattern, const std::string& robot) {
  std::string name = pattern;
  const std::string token = kRobotToken;
  for (size_t at = name.find(token); at != std::string::npos; at = name.find(token, at)) {
    name.replace(at, token.size(), robot);
    at += robot.size();
  }
  return name;
}

bot_core::pose_t ToPoseMessage(int64_t utime, const Pose2& pose, double tv_mps, double rv_radps) {
  bot_core::pose_t message{};
  message.utime = utime;
  message.pos[0] = pose.x();
  message.pos[1] = pose.y();
  message.vel[0] = tv_mps * std::cos(pose.theta());
  message.vel[1] = tv_mps * std::sin(pose.theta());
  message.orientation[0] = std::cos(0.5 * pose.theta());
  message.orientation[3] = std::sin(0.5 * pose.theta());
  message.rotation_rate[2] = rv_radps;
  return message;
}

bot_core::planar_lidar_t ToLidarMessage(const RobotScan& scan) {
  bot_core::planar_lidar_t message{};
  message.utime = scan.utime;
  message.nranges = static_cast<int32_t>(scan.ranges_m.size());
  message.ranges = scan.ranges_m;
  message.nintensities = static_cast<int32_t>(scan.intensities.size());
  message.intensities = scan.intensities;
  message.rad0 = scan.rad0;
  message.radstep = scan.radstep;
  return message;
}

Status WriteRobotStreams(const std::vector<RobotStream>& robots, const ImportChannels& channels,
                         const std::string& path, WriteCounts* counts) {
  if (Status s = channels.Validate(); !s.ok()) return s;
  *counts = WriteCounts();
  std::vector<Event> events;
  const bool shifted = std::any_of(robots.begin(), robots.end(),
                                   [](const RobotStream& r) { return r.time_shift_us != 0; });
  for (size_t r = 0; r < robots.size(); ++r) {
    const RobotStream& robot = robots[r];
    events.push_back({FirstUtime(robot), Kind::kLaserMount, r, 0});
    if (shifted) events.push_back({FirstUtime(robot), Kind::kClockShift, r, 0});
    for (size_t i = 0; i < robot.odometry.size(); ++i) {
      events.push_back({robot.odometry[i].utime, Kind::kOdometry, r, i});
    }
    for (size_t i = 0; i < robot.scans.size(); ++i) {
      events.push_back({robot.scans[i].utime, Kind::kScan, r, i});
    }
    for (size_t i = 0; i < robot.reference.size(); ++i) {
      events.push_back({robot.reference[i].utime, Kind::kReference, r, i});
    }
    for (size_t i = 0; i < robot.time_repairs.size(); ++i) {
      events.push_back({robot.time_repairs[i].utime, Kind::kTimeRepair, r, i});
    }
  }
  std::stable_sort(events.begin(), events.end(), [](const Event& a, const Event& b) {
    if (a.utime != b.utime) return a.utime < b.utime;
    if (a.kind != b.kind) return a.kind < b.kind;
    return a.robot < b.robot;
  });

  LcmLogWriter writer;
  if (Status s = writer.Open(path); !s.ok()) return s;
  std::vector<std::string> odometry_channel, laser_channel, reference_channel;
  for (const RobotStream& robot : robots) {
    odometry_channel.push_back(ChannelName(channels.odometry, robot.robot));
    laser_channel.push_back(ChannelName(channels.laser, robot.robot));
    reference_channel.push_back(ChannelName(channels.reference, robot.robot));
  }
  // Beside the laser channel, so that an agent finds it from the laser channel it reads.
  const auto mount_channel = [&](size_t r) { return laser_channel[r] + "_MOUNT"; };
  for (const Event& event : events) {
    const RobotStream& robot = robots[event.robot];
    Status status = Status::Ok();
    switch (event.kind) {
      case Kind::kLaserMount: {
        status = writer.Write(mount_channel(event.robot), event.utime,
                              ToPoseMessage(event.utime, robot.T_body_laser));
        ++counts->laser_mounts;
        break;
      }
      case Kind::kClockShift: {
        status = writer.Write(channels::ClockShift(robot.robot), event.utime,
                              ToPoseMessage(robot.time_shift_us, Pose2()));
        ++counts->clock_shifts;
        break;
      }
      case Kind::kTimeRepair: {
        bot_core::pose_t message{};
        message.utime = event.utime;
        message.pos[0] =
            static_cast<double>(robot.time_repairs[event.index].stamped_minus_repaired_us);
        message.orientation[0] = 1.0;
        status = writer.Write(channels::TimeRepair(robot.robot), event.utime, message);
        ++counts->time_repairs;
        break;
      }
      case Kind::kOdometry: {
        const RobotOdometrySample& s = robot.odometry[event.index];
        status = writer.Write(odometry_channel[event.robot], s.utime,
                              ToPoseMessage(s.utime, s.pose, s.tv_mps, s.rv_radps));
        ++counts->odometry;
        break;
      }
      case Kind::kScan: {
        const RobotScan& scan = robot.scans[event.index];
        status = writer.Write(laser_channel[event.robot], scan.utime, ToLidarMessage(scan));
        ++counts->scans;
        break;
      }
      case Kind::kReference: {
        const StampedPose2& pose = robot.reference[event.index];
        status = writer.Write(reference_channel[event.robot], pose.utime,
                              ToPoseMessage(pose.utime, pose.pose));
        ++counts->reference;
        break;
      }
    }
    if (!status.ok()) return Status::Error(path + ": " + status.message());
  }
  writer.Close();
  return Status::Ok();
}

}  // namespace anchormap
