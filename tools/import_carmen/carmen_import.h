#pragma once
// Reading a whole CARMEN log into memory with the statistics the importer prints: counts by
// message type, malformed lines, time steps backwards, and the signature of a "corrected" log
// (an ODOM line right after each scan that repeats the scan's pose with a bogus timestamp:
// see ../shared/data/SOURCES.md). No LCM here.

#include <cstdint>
#include <map>
#include <string>
#include <vector>

#include "common/util/status.h"
#include "tools/import_carmen/carmen_log.h"

namespace anchormap {

struct CarmenLogStats {
  int64_t lines = 0;             // every line of the file
  int64_t odometry_lines = 0;    // valid ODOM lines
  int64_t flaser_lines = 0;      // valid FLASER lines
  int64_t robotlaser_lines = 0;  // valid ROBOTLASER1 lines
  int64_t comment_or_blank_lines = 0;
  std::map<std::string, int64_t> ignored_by_type;  // PARAM, RAWLASER1, NEFF, ...
  int64_t malformed_lines = 0;                     // only non-zero with lenient reading
  std::vector<std::string> malformed_examples;     // "PATH:LINE: reason", the first 20
  // ODOM lines right after a laser line repeating its robot pose with a bogus time stamp
  // (below 1 ms, or more than 1 s before the scan's): the re-anchoring of a corrected log.
  // They are given the scan's time stamp.
  int64_t reanchored_odometry_lines = 0;
  int64_t odometry_steps_back = 0;  // ODOM time stamps earlier than the previous ODOM's
  int64_t laser_steps_back = 0;     // the same for laser lines
  std::map<int, int64_t> scans_by_beam_count;

  int64_t scans() const { return flaser_lines + robotlaser_lines; }
};

struct CarmenLogContents {
  std::vector<CarmenOdometry> odometry;  // file order
  std::vector<CarmenLaser> lasers;       // file order
  CarmenLogStats stats;

  // True when the odometry was re-anchored at the scans (a corrected log): its ODOM lines
  // then contain the published mapping result and must not be used as raw odometry.
  // (Most scans are followed by such a line.)
  bool LooksCorrected() const {
    return stats.scans() > 0 && 2 * stats.reanchored_odometry_lines > stats.scans();
  }
};

// Reads the log at `path` (plain or gzip). Without `lenient` the first malformed line fails
// with "PATH:LINE: reason"; with it malformed lines are skipped and counted. Unknown message
// types are never errors: they are counted in ignored_by_type. A read error (corrupt gzip)
// always fails.
Status ReadCarmenLog(const std::string& path, bool lenient, CarmenLogContents* contents);

// The laser's pose in the robot body frame as logged: the median, component by component, of
// Between(robot_pose, laser_pose) over the laser lines (identity without laser lines). Raw
// logs show the mounting offset here (fr079: x = -0.04 m); corrected logs, whose two poses are
// the same corrected pose, give the identity.
Pose2 EstimateLaserMounting(const CarmenLogContents& contents);

}  // namespace anchormap
