#pragma once
// How the bus names a trajectory: the robot's name and the trajectory id its agent drew at
// start (random, agent/trajectory_id.h). Unique together, and only together: two robots may
// draw the same number. The server maps a name to its solver's TrajectoryId
// (server/trajectory_table.h); the two are different types so they cannot be mixed up.

#include <cstdint>
#include <string>
#include <tuple>

namespace anchormap {

struct TrajectoryName {
  std::string robot;
  int64_t id = 0;  // the agent's trajectory id (`trajectory_id` on the wire)

  std::string ToString() const { return robot + "/" + std::to_string(id); }
  friend bool operator==(const TrajectoryName& a, const TrajectoryName& b) {
    return a.robot == b.robot && a.id == b.id;
  }
  friend bool operator!=(const TrajectoryName& a, const TrajectoryName& b) { return !(a == b); }
  friend bool operator<(const TrajectoryName& a, const TrajectoryName& b) {
    return std::tie(a.robot, a.id) < std::tie(b.robot, b.id);
  }
};

}  // namespace anchormap
