#pragma once
// From the lines of a CARMEN log to what the importer publishes per robot (no LCM): time
// ordering, the choice of odometry source, and --split, which cuts one robot's log into N
// consecutive pieces that become N independent robots (the thesis did this with its Stata
// Center data).
//
// Frames: without a split the odometry stays in the log's odometry frame. With a split each
// piece's odometry is re-expressed in its own frame, whose origin is the piece's first
// odometry pose (so every piece starts at the identity, as a freshly started robot would).
// The reference (the laser lines' x y theta) always stays in the log's frame: one common frame
// for all pieces is what lets the evaluation align the merged map with a single transform.
//
// Times: the log's, unless --simultaneous shifts every piece to start when the first does (the
// robots then explore at the same time, as a real team does); each robot's shift is kept so that
// the evaluation can map times back to the log's clock (the relations').

#include <cstdint>
#include <string>
#include <vector>

#include "common/types/stamped_pose2.h"
#include "common/util/status.h"
#include "tools/import_carmen/carmen_import.h"

namespace anchormap {

enum class OdometrySource {
  // ODOM lines when the log has any and its laser lines' times never step back in file order,
  // otherwise the laser lines' robot poses (see RepairedLaserTimes)
  kAuto,
  kOdomLines,   // the ODOM lines
  kLaserLines,  // the odom_x odom_y odom_theta fields of the laser lines
};

struct CarmenImportOptions {
  // Robot name (upper-case token). With split > 1 the pieces are named from it: R1 -> R1, R2,
  // ...; R4 -> R4, R5, ...; ALPHA -> ALPHA1, ALPHA2, ...
  std::string robot = "R1";
  // Number of consecutive pieces of equal duration; each becomes its own robot.
  int split = 1;
  // Time dropped around each cut (centred on it), as a fraction of the log's duration. The gap
  // keeps consecutive pieces from sharing scans of the same place at the same moment.
  double gap_fraction = 0.02;
  // When >= 0, the gap in seconds (overrides gap_fraction).
  double gap_s = -1.0;
  // Skip and count malformed lines instead of failing on the first.
  bool lenient = false;
  OdometrySource odometry_source = OdometrySource::kAuto;
  // With split > 1: shift each piece's times so that all start together.
  bool simultaneous = false;

  // An empty status when usable, otherwise the offending field and why.
  Status Validate() const;
};

struct RobotOdometrySample {
  int64_t utime = 0;
  Pose2 pose;  // in the robot's odometry frame (see the file comment)
  double tv_mps = 0.0;
  double rv_radps = 0.0;
};

struct RobotScan {
  int64_t utime = 0;
  float rad0 = 0.0f;     // angle of ranges[0], radians
  float radstep = 0.0f;  // angle between ranges, radians
  std::vector<float> ranges_m;
  std::vector<float> intensities;  // ROBOTLASER1 remissions, else empty
};

// Everything one robot publishes, each vector sorted by time (ties keep file order).
struct RobotStream {
  std::string robot;
  std::vector<RobotOdometrySample> odometry;
  std::vector<RobotScan> scans;
  StampedTrajectory reference;  // laser poses at the scans' times, in the log's frame
  Pose2 T_log_odometry;         // this robot's odometry frame in the log's odometry frame
  // Added to the log's times of everything above (--simultaneous; 0 otherwise).
  int64_t time_shift_us = 0;
  // The laser's pose in the robot body frame (EstimateLaserMounting).
  Pose2 T_body_laser;
  // Scans whose log time stepped back in file order and was repaired (RepairedLaserTimes):
  // `utime` is the scan's time here (shifted like the rest), `stamped_minus_repaired_us` what
  // the log stamped minus the repaired time, so that anchormap-eval finds the relations' scans.
  struct TimeRepair {
    int64_t utime = 0;
    int64_t stamped_minus_repaired_us = 0;
  };
  std::vector<TimeRepair> time_repairs;
};

struct SplitSummary {
  OdometrySource odometry_source_used = OdometrySource::kOdomLines;
  int64_t first_utime = 0;  // over odometry and scans, after sorting
  int64_t last_utime = 0;
  std::vector<int64_t> cut_utimes;  // N - 1 cut times
  int64_t gap_us = 0;
  int64_t dropped_odometry = 0;  // inside the gaps
  int64_t dropped_scans = 0;
  int64_t repaired_scan_times = 0;  // laser lines whose time stepped back (RepairedLaserTimes)
  double duration_s() const { return 1e-6 * static_cast<double>(last_utime - first_utime); }
};

// Time stamp in seconds -> LCM utime in microseconds (rounded).
int64_t SecondsToUtime(double seconds);

// The robot names of `count` pieces made from `robot` (see CarmenImportOptions::robot).
std::vector<std::string> PieceRobotNames(const std::string& robot, int count);

// The laser lines' times in microseconds, in file order, made strictly increasing. Some logs
// (Intel) have runs of lines stamped up to a second earlier than the line before them although
// their odometry poses continue the motion in file order: file order is the true order, the
// stamps are wrong. A run of lines stamped before the last good one gets times spread evenly
// between that line and the next line stamped after it (1 us apart after the last good one at
// the log's end); *repaired counts them. The relations files name scans by their stamps.
std::vector<int64_t> RepairedLaserTimes(const std::vector<CarmenLaser>& lasers, int64_t* repaired);

// Builds one stream per robot. Fails when the log has no odometry or no scans, or when a piece
// ends up without odometry (a gap too large for the log).
Status BuildRobotStreams(const CarmenLogContents& contents, const CarmenImportOptions& options,
                         std::vector<RobotStream>* robots, SplitSummary* summary);

}  // namespace anchormap
