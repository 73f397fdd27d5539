#include "tools/eval/clock_shift.h"

#include <cmath>

#include "common/bus/channels.h"

namespace anchormap {
namespace {

void Shift(int64_t shift_us, StampedTrajectory* poses) {
  for (StampedPose2& pose : *poses) pose.utime -= shift_us;
}

}  // namespace

Status ReadClockShifts(const std::string& path, std::map<std::string, int64_t>* shift_by_robot) {
  shift_by_robot->clear();
  std::map<std::string, StampedTrajectory> messages;
  int64_t undecodable = 0;
  if (Status s = ReadPoseChannels(path, channels::kClockShiftSuffix, &messages, &undecodable);
      !s.ok()) {
    return s;
  }
  if (undecodable > 0) {
    return Status::Error(path + ": " + std::to_string(undecodable) +
                         " clock shift messages do not decode");
  }
  for (const auto& [robot, shifts] : messages) {
    for (const StampedPose2& shift : shifts) {
      if (shift.utime != shifts.front().utime) {
        return Status::Error(path + ": robot " + robot + " has two different clock shifts");
      }
    }
    if (!shifts.empty()) (*shift_by_robot)[robot] = shifts.front().utime;
  }
  return Status::Ok();
}

void ShiftToLogClock(const std::map<std::string, int64_t>& shift_by_robot, MapEstimate* estimate,
                     std::map<std::string, StampedTrajectory>* odometry_by_robot) {
  for (const auto& [robot, shift_us] : shift_by_robot) {
    for (EstimatedTrajectory& trajectory : estimate->trajectories) {
      if (trajectory.robot == robot) Shift(shift_us, &trajectory.poses);
    }
    if (odometry_by_robot == nullptr) continue;
    const auto odometry = odometry_by_robot->find(robot);
    if (odometry != odometry_by_robot->end()) Shift(shift_us, &odometry->second);
  }
}

Status ReadTimeRepairs(const std::string& path,
                       const std::map<std::string, int64_t>& shift_by_robot,
                       std::map<int64_t, int64_t>* repaired_by_stamp) {
  repaired_by_stamp->clear();
  std::map<std::string, StampedTrajectory> messages;
  int64_t undecodable = 0;
  if (Status s = ReadPoseChannels(path, channels::kTimeRepairSuffix, &messages, &undecodable);
      !s.ok()) {
    return s;
  }
  if (undecodable > 0) {
    return Status::Error(path + ": " + std::to_string(undecodable) +
                         " time repair messages do not decode");
  }
  for (const auto& [robot, repairs] : messages) {
    const auto shift = shift_by_robot.find(robot);
    const int64_t shift_us = shift == shift_by_robot.end() ? 0 : shift->second;
    for (const StampedPose2& repair : repairs) {
      const int64_t repaired = repair.utime - shift_us;
      (*repaired_by_stamp)[repaired + std::llround(repair.pose.x())] = repaired;
    }
  }
  return Status::Ok();
}

int64_t ApplyTimeRepairs(const std::map<int64_t, int64_t>& repaired_by_stamp,
                         std::vector<Relation>* relations) {
  int64_t moved = 0;
  const auto repair = [&](double* t_s) {
    const auto found = repaired_by_stamp.find(std::llround(*t_s * 1e6));
    if (found == repaired_by_stamp.end()) return;
    *t_s = 1e-6 * static_cast<double>(found->second);
    ++moved;
  };
  for (Relation& relation : *relations) {
    repair(&relation.t1_s);
    repair(&relation.t2_s);
  }
  return moved;
}

}  // namespace anchormap
