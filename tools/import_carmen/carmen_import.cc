#include "tools/import_carmen/carmen_import.h"

#include <algorithm>

namespace anchormap {
namespace {

constexpr size_t kMaxMalformedExamples = 20;

bool SamePose(const Pose2& a, const Pose2& b) {
  return a.x() == b.x() && a.y() == b.y() && a.theta() == b.theta();
}

// The re-anchoring lines of the corrected logs carry time stamp 0, a denormal (1e-42) or a
// small number (0.71 at 1055.56 s): uninitialised memory. Raw logs also repeat a scan's pose
// when the robot stands still, with a real time stamp at most 0.9 s off (intel.clf).
bool IsBogusTime(double odometry_time_s, double scan_time_s) {
  constexpr double kZeroTimeS = 1e-3;
  constexpr double kMaxRealStepBackS = 1.0;
  return odometry_time_s < scan_time_s &&
         (odometry_time_s < kZeroTimeS || odometry_time_s < scan_time_s - kMaxRealStepBackS);
}

}  // namespace

Status ReadCarmenLog(const std::string& path, bool lenient, CarmenLogContents* contents) {
  *contents = CarmenLogContents();
  CarmenLogStats& stats = contents->stats;
  CarmenLogReader reader;
  if (Status s = reader.Open(path); !s.ok()) return s;

  std::string line;
  CarmenRecord record;
  bool previous_was_laser = false;  // the previous line of the file was a valid laser line
  double last_odometry_time_s = 0.0, last_laser_time_s = 0.0;
  while (reader.ReadLine(&line)) {
    ++stats.lines;
    const Status parsed = ParseCarmenLine(line, &record);
    if (!parsed.ok()) {
      const std::string message =
          path + ":" + std::to_string(reader.line_number()) + ": " + parsed.message();
      if (!lenient) return Status::Error(message);
      ++stats.malformed_lines;
      if (stats.malformed_examples.size() < kMaxMalformedExamples) {
        stats.malformed_examples.push_back(message);
      }
      previous_was_laser = false;
      continue;
    }
    switch (record.kind) {
      case CarmenRecord::Kind::kIgnored:
        if (record.type.empty() || record.type == "#") {
          ++stats.comment_or_blank_lines;
        } else {
          ++stats.ignored_by_type[record.type];
        }
        previous_was_laser = false;
        break;
      case CarmenRecord::Kind::kOdometry: {
        CarmenOdometry& odometry = record.odometry;
        if (previous_was_laser) {
          const CarmenLaser& scan = contents->lasers.back();
          if (SamePose(odometry.pose, scan.robot_pose) &&
              IsBogusTime(odometry.ipc_time_s, scan.ipc_time_s)) {
            ++stats.reanchored_odometry_lines;
            odometry.ipc_time_s = scan.ipc_time_s;
            odometry.logger_time_s = scan.logger_time_s;
          }
        }
        if (!contents->odometry.empty() && odometry.ipc_time_s < last_odometry_time_s) {
          ++stats.odometry_steps_back;
        }
        last_odometry_time_s = odometry.ipc_time_s;
        ++stats.odometry_lines;
        contents->odometry.push_back(odometry);
        previous_was_laser = false;
        break;
      }
      case CarmenRecord::Kind::kLaser: {
        const CarmenLaser& scan = record.laser;
        if (!contents->lasers.empty() && scan.ipc_time_s < last_laser_time_s) {
          ++stats.laser_steps_back;
        }
        last_laser_time_s = scan.ipc_time_s;
        if (scan.format == CarmenLaserFormat::kFlaser) {
          ++stats.flaser_lines;
        } else {
          ++stats.robotlaser_lines;
        }
        ++stats.scans_by_beam_count[static_cast<int>(scan.ranges_m.size())];
        contents->lasers.push_back(scan);
        previous_was_laser = true;
        break;
      }
    }
  }
  if (!reader.status().ok()) return reader.status();
  return Status::Ok();
}

Pose2 EstimateLaserMounting(const CarmenLogContents& contents) {
  if (contents.lasers.empty()) return Pose2();
  std::vector<double> x, y, theta;
  for (const CarmenLaser& laser : contents.lasers) {
    const Pose2 T_body_laser = Between(laser.robot_pose, laser.laser_pose);
    x.push_back(T_body_laser.x());
    y.push_back(T_body_laser.y());
    theta.push_back(T_body_laser.theta());
  }
  const auto median = [](std::vector<double>& v) {
    std::nth_element(v.begin(), v.begin() + v.size() / 2, v.end());
    return v[v.size() / 2];
  };
  return Pose2(median(x), median(y), median(theta));
}

}  // namespace anchormap
