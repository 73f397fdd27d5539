#pragma once
// TUM-style trajectory files: one pose a line, "timestamp x y z qx qy qz qw" (seconds,
// metres, unit quaternion), '#' comments, fields separated by spaces or commas. The format of
// the TUM RGB-D benchmark scripts and of evo, so that estimates and references exported by
// anchormap open in those tools. 2D poses are written with z = 0 and a yaw-only quaternion;
// reading keeps x, y and the quaternion's yaw (roll and pitch, if any, are dropped).

#include <string>
#include <string_view>

#include "common/types/stamped_pose2.h"
#include "common/util/status.h"

namespace anchormap {

// Parses one data line. Returns an error naming the reason (field count, a field that is not
// a finite number, a quaternion whose norm is not 1 within 1e-3). Comments and blank lines
// are the caller's business (ReadTrajectoryFile skips them).
Status ParseTrajectoryLine(std::string_view line, StampedPose2* pose);

// The line written for `pose`: time with microsecond resolution, coordinates with 10
// significant digits, no newline.
std::string FormatTrajectoryLine(const StampedPose2& pose);

// Reads a whole file; errors are "PATH:LINE: reason". Poses are returned in file order.
Status ReadTrajectoryFile(const std::string& path, StampedTrajectory* poses);

// Writes `poses` with a one-line '#' header naming the columns (and `comment` if not empty).
Status WriteTrajectoryFile(const std::string& path, const StampedTrajectory& poses,
                           const std::string& comment = "");

}  // namespace anchormap
