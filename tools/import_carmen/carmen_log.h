#pragma once
// CARMEN log files (the format of the Radish repository and of the Freiburg SLAM benchmark,
// Kümmerle et al. 2009): a streaming line reader for plain or gzip-compressed files, and a
// strict parser of the three message types anchormap imports.
//
//   ODOM x y theta tv rv accel ipc_timestamp host logger_timestamp
//   FLASER n r1..rn x y theta odom_x odom_y odom_theta ipc_timestamp host logger_timestamp
//   ROBOTLASER1 laser_type start_angle fov angular_resolution max_range accuracy
//       remission_mode n r1..rn m e1..em laser_x laser_y laser_theta robot_x robot_y
//       robot_theta tv rv forward_safety_dist side_safety_dist turn_axis
//       ipc_timestamp host logger_timestamp
//
// (field order as CARMEN's own readers, carmen_string_to_base_odometry_message,
// carmen_string_to_robot_laser_message_orig and carmen_string_to_robot_laser_message.)
// FLASER lines carry no laser geometry; like CARMEN we take start angle -pi/2 and a
// resolution of 1 degree for 180/181 beams, 0.5 degree for 360/361, 0.25 degree for 400/401,
// otherwise pi / (n - 1). Every other message type (PARAM, RAWLASER1, RLASER, NEFF, SYNC, ...),
// '#' comments and blank lines are recognised and ignored. Unlike CARMEN's strtod-based reader,
// which reads garbage as zeros, every field must be a finite number and the field count must
// match exactly; a failure says which field and why.

#include <cstdint>
#include <memory>
#include <string>
#include <string_view>
#include <vector>

#include "common/geometry/pose2.h"
#include "common/util/status.h"

namespace anchormap {

// One ODOM line: the robot's wheel-odometry pose in the odometry frame.
struct CarmenOdometry {
  Pose2 pose;               // x, y (metres), theta (radians)
  double tv_mps = 0.0;      // translational velocity
  double rv_radps = 0.0;    // rotational velocity
  double accel_mps2 = 0.0;  // CARMEN's acceleration field (a base setting, not a measurement)
  double ipc_time_s = 0.0;  // time stamp of the message (what CARMEN tools use)
  double logger_time_s = 0.0;
};

enum class CarmenLaserFormat { kFlaser, kRobotLaser1 };

// One FLASER or ROBOTLASER1 line: a front laser scan with the poses logged beside it.
struct CarmenLaser {
  CarmenLaserFormat format = CarmenLaserFormat::kFlaser;
  double start_angle_rad = 0.0;         // angle of ranges_m[0] in the laser frame
  double angular_resolution_rad = 0.0;  // angle between consecutive ranges
  double fov_rad = 0.0;
  double max_range_m = 0.0;  // ROBOTLASER1 only (0 for FLASER: unknown)
  std::vector<float> ranges_m;
  std::vector<float> remissions;  // ROBOTLASER1 only
  Pose2 laser_pose;       // "x y theta": the laser's pose (in corrected logs a mapping result)
  Pose2 robot_pose;       // "odom_x odom_y odom_theta": the robot's odometry pose at the scan
  double tv_mps = 0.0;    // ROBOTLASER1 only
  double rv_radps = 0.0;  // ROBOTLASER1 only
  double ipc_time_s = 0.0;
  double logger_time_s = 0.0;
};

// A parsed line. `type` is the message name ("ODOM", "PARAM", ...), "#" for a comment and
// "" for a blank line; only the member matching `kind` is filled.
struct CarmenRecord {
  enum class Kind { kOdometry, kLaser, kIgnored };
  Kind kind = Kind::kIgnored;
  std::string type;
  CarmenOdometry odometry;
  CarmenLaser laser;
};

// The beam geometry CARMEN assumes for a FLASER line of `num_readings` ranges.
double CarmenFlaserAngularResolution(int num_readings);
double CarmenFlaserFov(int num_readings);

// Parses one line (a trailing newline is allowed). Returns an error whose message is the
// reason without file or line ("FLASER: range 3 'x' is not a finite number").
Status ParseCarmenLine(std::string_view line, CarmenRecord* record);

// Reads a CARMEN log line by line through zlib, so plain and gzip files both work.
class CarmenLogReader {
 public:
  CarmenLogReader();
  ~CarmenLogReader();
  CarmenLogReader(const CarmenLogReader&) = delete;
  CarmenLogReader& operator=(const CarmenLogReader&) = delete;

  Status Open(const std::string& path);
  // The next line without its newline; false at the end of the file or after a read error
  // (a corrupt or truncated gzip stream, a line longer than 64 MiB): then status() says why.
  bool ReadLine(std::string* line);
  // 1-based number of the line last returned.
  int64_t line_number() const { return line_number_; }
  const Status& status() const { return status_; }

 private:
  struct File;
  std::unique_ptr<File> file_;
  std::string path_;
  int64_t line_number_ = 0;
  Status status_ = Status::Ok();
};

}  // namespace anchormap
