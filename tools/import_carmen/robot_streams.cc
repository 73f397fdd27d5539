#include "tools/import_carmen/robot_streams.h"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <numeric>

namespace anchormap {
namespace {

bool IsRobotName(const std::string& name) {
  if (name.empty() || name.front() < 'A' || name.front() > 'Z') return false;
  return std::all_of(name.begin(), name.end(), [](char c) {
    return (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') || c == '_';
  });
}

std::string Seconds(int64_t utime) {
  char buffer[64];
  std::snprintf(buffer, sizeof(buffer), "%.3f s", 1e-6 * static_cast<double>(utime));
  return buffer;
}

int64_t FirstUtime(const RobotStream& robot) {
  int64_t first = robot.odometry.front().utime;
  if (!robot.scans.empty()) first = std::min(first, robot.scans.front().utime);
  return first;
}

// Every piece moved in time to start when the first does; the shift is kept per robot.
void ShiftPiecesToStartTogether(std::vector<RobotStream>* robots) {
  const int64_t start = FirstUtime(robots->front());
  for (RobotStream& robot : *robots) {
    robot.time_shift_us = start - FirstUtime(robot);
    for (RobotOdometrySample& sample : robot.odometry) sample.utime += robot.time_shift_us;
    for (RobotScan& scan : robot.scans) scan.utime += robot.time_shift_us;
    for (StampedPose2& pose : robot.reference) pose.utime += robot.time_shift_us;
    for (RobotStream::TimeRepair& repair : robot.time_repairs) repair.utime += robot.time_shift_us;
  }
}

}  // namespace

Status CarmenImportOptions::Validate() const {
  if (!IsRobotName(robot)) {
    return Status::Error("robot: '" + robot + "' is not an upper-case name like R1");
  }
  if (split < 1 || split > 100) {
    return Status::Error("split: " + std::to_string(split) + " is not in [1, 100]");
  }
  if (!(gap_fraction >= 0.0) || (split - 1) * gap_fraction >= 1.0 || gap_fraction >= 0.5) {
    return Status::Error("gap_fraction: " + std::to_string(gap_fraction) +
                         " must be >= 0, < 0.5 and leave time for every piece");
  }
  if (!std::isfinite(gap_s)) return Status::Error("gap_s: not a finite number");
  if (simultaneous && split < 2) return Status::Error("simultaneous: needs split >= 2");
  return Status::Ok();
}

int64_t SecondsToUtime(double seconds) { return std::llround(seconds * 1e6); }

std::vector<std::string> PieceRobotNames(const std::string& robot, int count) {
  if (count <= 1) return {robot};
  size_t digits_at = robot.size();
  while (digits_at > 0 && std::isdigit(static_cast<unsigned char>(robot[digits_at - 1]))) {
    --digits_at;
  }
  const std::string prefix = robot.substr(0, digits_at);
  const int64_t first =
      digits_at < robot.size() ? std::stoll(robot.substr(digits_at).substr(0, 9)) : 1;
  std::vector<std::string> names;
  for (int i = 0; i < count; ++i) names.push_back(prefix + std::to_string(first + i));
  return names;
}

std::vector<int64_t> RepairedLaserTimes(const std::vector<CarmenLaser>& lasers, int64_t* repaired) {
  *repaired = 0;
  std::vector<int64_t> utimes(lasers.size());
  size_t i = 0;
  while (i < lasers.size()) {
    const int64_t stamped = SecondsToUtime(lasers[i].ipc_time_s);
    if (i == 0 || stamped > utimes[i - 1]) {
      utimes[i] = stamped;
      ++i;
      continue;
    }
    // A run [i, end) stamped at or before the last good time; `end` is stamped after it.
    const int64_t last_good = utimes[i - 1];
    size_t end = i;
    while (end < lasers.size() && SecondsToUtime(lasers[end].ipc_time_s) <= last_good) ++end;
    const int64_t run = static_cast<int64_t>(end - i);
    const int64_t span =
        end < lasers.size() ? SecondsToUtime(lasers[end].ipc_time_s) - last_good : run + 1;
    for (int64_t k = 0; k < run; ++k) {
      // Evenly inside (last_good, next): at least 1 us apart when the span is tiny.
      utimes[i + static_cast<size_t>(k)] =
          last_good + std::max<int64_t>(k + 1, span * (k + 1) / (run + 1));
    }
    *repaired += run;
    i = end;
  }
  return utimes;
}

Status BuildRobotStreams(const CarmenLogContents& contents, const CarmenImportOptions& options,
                         std::vector<RobotStream>* robots, SplitSummary* summary) {
  if (Status s = options.Validate(); !s.ok()) return s;
  *summary = SplitSummary();
  robots->clear();

  // Odometry in the log's frame, sorted by time; std::stable_sort keeps file order for ties.
  OdometrySource source = options.odometry_source;
  int64_t repaired = 0;
  const std::vector<int64_t> laser_utimes = RepairedLaserTimes(contents.lasers, &repaired);
  if (source == OdometrySource::kAuto) {
    // The ODOM lines' stamps step back with the lasers' and cannot be put in order against
    // them; the laser lines' own odometry poses sit exactly at the repaired scan times.
    source = contents.odometry.empty() || repaired > 0 ? OdometrySource::kLaserLines
                                                       : OdometrySource::kOdomLines;
  }
  summary->repaired_scan_times = repaired;
  summary->odometry_source_used = source;
  std::vector<RobotOdometrySample> odometry;
  if (source == OdometrySource::kOdomLines) {
    for (const CarmenOdometry& o : contents.odometry) {
      odometry.push_back({SecondsToUtime(o.ipc_time_s), o.pose, o.tv_mps, o.rv_radps});
    }
  } else {
    for (size_t i = 0; i < contents.lasers.size(); ++i) {
      const CarmenLaser& l = contents.lasers[i];
      odometry.push_back({laser_utimes[i], l.robot_pose, l.tv_mps, l.rv_radps});
    }
  }
  const auto by_time = [](const auto& a, const auto& b) { return a.utime < b.utime; };
  std::stable_sort(odometry.begin(), odometry.end(), by_time);

  std::vector<size_t> scan_order(contents.lasers.size());
  std::iota(scan_order.begin(), scan_order.end(), 0);
  std::stable_sort(scan_order.begin(), scan_order.end(),
                   [&](size_t a, size_t b) { return laser_utimes[a] < laser_utimes[b]; });

  if (odometry.empty()) {
    return Status::Error(source == OdometrySource::kOdomLines
                             ? "the log has no ODOM lines (try the laser lines' odometry)"
                             : "the log has no laser lines to take odometry from");
  }
  if (scan_order.empty()) return Status::Error("the log has no FLASER or ROBOTLASER1 lines");

  const int64_t first_scan = laser_utimes[scan_order.front()];
  const int64_t last_scan = laser_utimes[scan_order.back()];
  summary->first_utime = std::min(odometry.front().utime, first_scan);
  summary->last_utime = std::max(odometry.back().utime, last_scan);
  const int pieces = options.split;
  const double duration_us = static_cast<double>(summary->last_utime - summary->first_utime);
  summary->gap_us = options.gap_s >= 0.0 ? SecondsToUtime(options.gap_s)
                                         : std::llround(options.gap_fraction * duration_us);
  for (int k = 1; k < pieces; ++k) {
    summary->cut_utimes.push_back(summary->first_utime + std::llround(duration_us * k / pieces));
  }
  // The piece a time belongs to, or -1 inside a gap.
  const auto piece_of = [&](int64_t utime) {
    const auto& cuts = summary->cut_utimes;
    const int k =
        static_cast<int>(std::upper_bound(cuts.begin(), cuts.end(), utime) - cuts.begin());
    if (k > 0 && 2 * (utime - cuts[k - 1]) < summary->gap_us) return -1;
    if (k < pieces - 1 && 2 * (cuts[k] - utime) < summary->gap_us) return -1;
    return k;
  };

  const std::vector<std::string> names = PieceRobotNames(options.robot, pieces);
  robots->resize(pieces);
  for (int k = 0; k < pieces; ++k) (*robots)[k].robot = names[k];
  for (const RobotOdometrySample& sample : odometry) {
    const int k = piece_of(sample.utime);
    if (k < 0) {
      ++summary->dropped_odometry;
      continue;
    }
    (*robots)[k].odometry.push_back(sample);
  }
  for (size_t index : scan_order) {
    const CarmenLaser& laser = contents.lasers[index];
    const int64_t utime = laser_utimes[index];
    const int k = piece_of(utime);
    if (k < 0) {
      ++summary->dropped_scans;
      continue;
    }
    RobotScan scan;
    scan.utime = utime;
    scan.rad0 = static_cast<float>(laser.start_angle_rad);
    scan.radstep = static_cast<float>(laser.angular_resolution_rad);
    scan.ranges_m = laser.ranges_m;
    scan.intensities = laser.remissions;
    (*robots)[k].scans.push_back(std::move(scan));
    (*robots)[k].reference.push_back({utime, laser.laser_pose});
    const int64_t stamped = SecondsToUtime(laser.ipc_time_s);
    if (stamped != utime) (*robots)[k].time_repairs.push_back({utime, stamped - utime});
  }

  const Pose2 T_body_laser = EstimateLaserMounting(contents);
  for (int k = 0; k < pieces; ++k) {
    RobotStream& robot = (*robots)[k];
    robot.T_body_laser = T_body_laser;
    if (robot.odometry.empty()) {
      const int64_t begin = k == 0 ? summary->first_utime : summary->cut_utimes[k - 1];
      const int64_t end = k == pieces - 1 ? summary->last_utime : summary->cut_utimes[k];
      return Status::Error("piece " + std::to_string(k + 1) + " (" + robot.robot +
                           ") has no odometry between " + Seconds(begin) + " and " + Seconds(end) +
                           ": gap too large for this log?");
    }
    if (pieces == 1) continue;  // the log's own frame
    robot.T_log_odometry = robot.odometry.front().pose;
    for (RobotOdometrySample& sample : robot.odometry) {
      sample.pose = Between(robot.T_log_odometry, sample.pose);
    }
  }
  if (options.simultaneous) ShiftPiecesToStartTogether(robots);
  return Status::Ok();
}

}  // namespace anchormap
