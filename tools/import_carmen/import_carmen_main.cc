// anchormap-import-carmen: converts a CARMEN log (plain or gzip) into an LCM log of bot_core
// messages: <R>_ODOMETRY, <R>_LASER and <R>_REFERENCE per robot (see docs/TOOLS-DATA.md).
// Exit status: 0 done, 1 bad or unreadable input, 2 bad command line.

#include <chrono>
#include <cstdio>
#include <iostream>
#include <string>

#include <boost/program_options.hpp>

#include "common/io/trajectory_file.h"
#include "tools/import_carmen/carmen_import.h"
#include "tools/import_carmen/robot_streams.h"
#include "tools/import_carmen/robot_streams_writer.h"

namespace po = boost::program_options;
using namespace anchormap;

namespace {

const char* kUsage =
    "Usage: anchormap-import-carmen IN.log[.gz] --output OUT.lcmlog [options]\n"
    "Converts a CARMEN log (ODOM, FLASER, ROBOTLASER1 lines; plain or gzip) into an LCM log:\n"
    "  <R>_ODOMETRY  bot_core.pose_t from the ODOM lines (raw odometry)\n"
    "  <R>_LASER     bot_core.planar_lidar_t from the laser lines\n"
    "  <R>_REFERENCE bot_core.pose_t, the laser lines' own pose (a mapping result in\n"
    "                \"corrected\" logs; raw odometry of the laser in raw logs)\n"
    "  <R>_LASER_MOUNT bot_core.pose_t, the laser's pose on the robot (read by the agent)\n"
    "  <R>_CLOCK_SHIFT with --simultaneous: the piece's time shift in utime (read by eval)\n"
    "Messages are sorted by time (ipc_timestamp). Other message types are counted and skipped.\n";

const char* SourceName(OdometrySource source) {
  switch (source) {
    case OdometrySource::kAuto:
      return "auto";
    case OdometrySource::kOdomLines:
      return "ODOM lines";
    case OdometrySource::kLaserLines:
      return "laser lines' odometry fields";
  }
  return "?";
}

void PrintSummary(const std::string& input, const std::string& output,
                  const CarmenLogContents& contents, const SplitSummary& split,
                  const std::vector<RobotStream>& robots, const WriteCounts& written,
                  double wall_s) {
  const CarmenLogStats& s = contents.stats;
  std::printf("anchormap-import-carmen: %s -> %s\n", input.c_str(), output.c_str());
  std::printf("  lines        %lld: ODOM %lld, FLASER %lld, ROBOTLASER1 %lld, comments/blank %lld",
              (long long)s.lines, (long long)s.odometry_lines, (long long)s.flaser_lines,
              (long long)s.robotlaser_lines, (long long)s.comment_or_blank_lines);
  for (const auto& [type, count] : s.ignored_by_type) {
    std::printf(", %s %lld (skipped)", type.c_str(), (long long)count);
  }
  std::printf(", malformed %lld\n", (long long)s.malformed_lines);
  if (s.reanchored_odometry_lines > 0) {
    std::printf(
        "  corrected    %lld ODOM lines re-anchor the odometry at a scan (time stamp "
        "replaced by the scan's)\n",
        (long long)s.reanchored_odometry_lines);
  }
  std::printf("  scans        %lld (", (long long)s.scans());
  bool first = true;
  for (const auto& [beams, count] : s.scans_by_beam_count) {
    std::printf("%s%lld of %d beams", first ? "" : ", ", (long long)count, beams);
    first = false;
  }
  std::printf(")\n");
  std::printf(
      "  time         %.6f .. %.6f s, duration %.3f s; steps back in file order: "
      "ODOM %lld, laser %lld; scan times repaired %lld (file order is the true order)\n",
      1e-6 * split.first_utime, 1e-6 * split.last_utime, split.duration_s(),
      (long long)s.odometry_steps_back, (long long)s.laser_steps_back,
      (long long)split.repaired_scan_times);
  const Pose2 mounting = EstimateLaserMounting(contents);
  std::printf(
      "  odometry     from %s; laser pose in the body frame (median over scans): "
      "x %.4f m, y %.4f m, theta %.4f rad\n",
      SourceName(split.odometry_source_used), mounting.x(), mounting.y(), mounting.theta());
  if (!split.cut_utimes.empty()) {
    std::printf(
        "  split        %zu pieces, gap %.3f s around each cut, dropped %lld odometry and "
        "%lld scans\n",
        robots.size(), 1e-6 * split.gap_us, (long long)split.dropped_odometry,
        (long long)split.dropped_scans);
  }
  for (const RobotStream& robot : robots) {
    std::printf(
        "  robot %-6s %zu odometry, %zu scans, %zu reference poses, %.3f .. %.3f s; "
        "odometry frame in the log's frame: (%.3f, %.3f, %.4f)\n",
        robot.robot.c_str(), robot.odometry.size(), robot.scans.size(), robot.reference.size(),
        1e-6 * robot.odometry.front().utime, 1e-6 * robot.odometry.back().utime,
        robot.T_log_odometry.x(), robot.T_log_odometry.y(), robot.T_log_odometry.theta());
    if (robot.time_shift_us != 0) {
      std::printf("               shifted by %.6f s to start with the first piece\n",
                  1e-6 * static_cast<double>(robot.time_shift_us));
    }
  }
  std::printf("  written      %lld odometry, %lld scans, %lld reference messages in %.2f s\n",
              (long long)written.odometry, (long long)written.scans, (long long)written.reference,
              wall_s);
}

}  // namespace

int main(int argc, char** argv) {
  const auto start = std::chrono::steady_clock::now();
  CarmenImportOptions options;
  ImportChannels channels;
  std::string input, output, odometry_source = "auto", reference_tum;

  po::options_description visible("Options");
  visible.add_options()("help,h", "print this help and exit")(
      "output,o", po::value(&output), "the LCM log to write (required; truncated)")(
      "robot", po::value(&options.robot)->default_value(options.robot),
      "robot name; with --split N the pieces are named from it (R1 -> R1..RN)")(
      "split", po::value(&options.split)->default_value(options.split),
      "cut the log by time into N consecutive pieces, each its own robot whose odometry starts "
      "at the origin")(
      "gap-fraction", po::value(&options.gap_fraction)->default_value(options.gap_fraction, "0.02"),
      "with --split: fraction of the log's duration dropped around each cut")(
      "gap-s", po::value(&options.gap_s),
      "with --split: seconds dropped around each cut (overrides --gap-fraction)")(
      "simultaneous", po::bool_switch(&options.simultaneous),
      "with --split: shift the pieces in time to start together (the robots explore at the same "
      "time); each shift is recorded for anchormap-eval")(
      "lenient", po::bool_switch(&options.lenient),
      "skip and count malformed lines instead of failing on the first")(
      "odometry-source", po::value(&odometry_source)->default_value(odometry_source),
      "auto | odom | laser: ODOM lines, or the laser lines' odom_x odom_y odom_theta fields "
      "(auto: ODOM lines when there are any)")(
      "odometry-channel", po::value(&channels.odometry)->default_value(channels.odometry),
      "channel pattern of the odometry ({robot} is replaced by the name)")(
      "laser-channel", po::value(&channels.laser)->default_value(channels.laser),
      "channel pattern of the scans")(
      "reference-channel", po::value(&channels.reference)->default_value(channels.reference),
      "channel pattern of the reference poses")(
      "reference-tum", po::value(&reference_tum),
      "also write each robot's reference as a TUM trajectory file PREFIX<robot>.txt");
  po::options_description hidden;
  hidden.add_options()("input", po::value(&input));
  po::options_description all;
  all.add(visible).add(hidden);
  po::positional_options_description positional;
  positional.add("input", 1);

  po::variables_map vm;
  try {
    po::store(po::command_line_parser(argc, argv).options(all).positional(positional).run(), vm);
    po::notify(vm);
  } catch (const std::exception& e) {
    std::cerr << "anchormap-import-carmen: " << e.what() << " (see --help)\n";
    return 2;
  }
  if (vm.count("help")) {
    std::cout << kUsage << "\n" << visible;
    return 0;
  }
  if (input.empty() || output.empty()) {
    std::cerr << "anchormap-import-carmen: an input file and --output are required (see --help)\n";
    return 2;
  }
  if (odometry_source == "auto") {
    options.odometry_source = OdometrySource::kAuto;
  } else if (odometry_source == "odom") {
    options.odometry_source = OdometrySource::kOdomLines;
  } else if (odometry_source == "laser") {
    options.odometry_source = OdometrySource::kLaserLines;
  } else {
    std::cerr << "anchormap-import-carmen: --odometry-source must be auto, odom or laser, not '"
              << odometry_source << "'\n";
    return 2;
  }
  if (!vm.count("gap-s")) options.gap_s = -1.0;
  for (const Status& status : {options.Validate(), channels.Validate()}) {
    if (!status.ok()) {
      std::cerr << "anchormap-import-carmen: bad option: " << status.message() << "\n";
      return 2;
    }
  }

  CarmenLogContents contents;
  if (Status s = ReadCarmenLog(input, options.lenient, &contents); !s.ok()) {
    std::cerr << s.message() << "\n";
    return 1;
  }
  const CarmenLogStats& stats = contents.stats;
  for (const std::string& message : stats.malformed_examples) {
    std::cerr << message << " (skipped)\n";
  }
  if (stats.malformed_lines > static_cast<int64_t>(stats.malformed_examples.size())) {
    std::cerr << "... and " << stats.malformed_lines - stats.malformed_examples.size()
              << " more malformed lines skipped\n";
  }
  if (contents.LooksCorrected()) {
    std::cerr << "warning: " << input
              << " looks like a CORRECTED log: " << stats.reanchored_odometry_lines
              << " ODOM lines re-anchor the odometry at a scan's pose (imported with the scan's "
                 "time). Its odometry contains the published mapping result: use this import "
                 "as a reference, not as input to the mapper.\n";
  }
  if (stats.flaser_lines > 0 && stats.robotlaser_lines > 0) {
    std::cerr << "warning: the log has both FLASER and ROBOTLASER1 lines; both are imported, so "
                 "scans may be duplicated\n";
  }

  std::vector<RobotStream> robots;
  SplitSummary split;
  if (Status s = BuildRobotStreams(contents, options, &robots, &split); !s.ok()) {
    std::cerr << "anchormap-import-carmen: " << input << ": " << s.message() << "\n";
    return 1;
  }
  WriteCounts written;
  if (Status s = WriteRobotStreams(robots, channels, output, &written); !s.ok()) {
    std::cerr << "anchormap-import-carmen: " << s.message() << "\n";
    return 1;
  }
  if (!reference_tum.empty()) {
    for (const RobotStream& robot : robots) {
      const std::string path = reference_tum + robot.robot + ".txt";
      if (Status s =
              WriteTrajectoryFile(path, robot.reference, robot.robot + " reference from " + input);
          !s.ok()) {
        std::cerr << "anchormap-import-carmen: " << s.message() << "\n";
        return 1;
      }
    }
  }
  const double wall_s =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  PrintSummary(input, output, contents, split, robots, written, wall_s);
  return 0;
}
