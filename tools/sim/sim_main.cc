// anchormap-sim: a deterministic multi-robot simulator that writes an LCM log of raw
// robot data (odometry, laser, encounters) plus ground truth. See docs/TOOLS-SIM.md.

#include <chrono>
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <string>

#include <boost/program_options.hpp>

#include "tools/sim/sim_log.h"

namespace po = boost::program_options;
using anchormap::sim::SimOptions;

namespace {

constexpr double kDegPerRad = 180.0 / anchormap::kPi;

void PrintSummary(const SimOptions& options, const anchormap::sim::SimSummary& summary,
                  const std::string& path, double wall_s) {
  std::error_code ignored;
  const auto bytes = std::filesystem::file_size(path, ignored);
  std::printf("anchormap-sim: %d robots, %.1f s simulated, world %.1f x %.1f m, seed %llu\n",
              summary.robots, options.duration_s, summary.world_max.x() - summary.world_min.x(),
              summary.world_max.y() - summary.world_min.y(),
              static_cast<unsigned long long>(options.seed));
  double total_distance = 0.0;
  for (double d : summary.distance_m) total_distance += d;
  std::printf("  scans %lld, encounters %lld between %zu robot pairs, driven %.0f m in total\n",
              static_cast<long long>(summary.scans), static_cast<long long>(summary.encounters),
              summary.encounters_by_pair.size(), total_distance);
  int shown = 0;
  for (const auto& [pair, count] : summary.encounters_by_pair) {
    if (shown++ == 12) {
      std::printf("  ...\n");
      break;
    }
    std::printf("  encounters %s-%s: %d\n", anchormap::sim::RobotName(pair.first).c_str(),
                anchormap::sim::RobotName(pair.second).c_str(), count);
  }
  if (summary.planning_failures > 0) {
    std::printf("  route planning failed %d times (robots waited and retried)\n",
                summary.planning_failures);
  }
  std::printf("  wrote %lld events (%.1f MB) to %s in %.1f s\n",
              static_cast<long long>(summary.events), static_cast<double>(bytes) / 1e6,
              path.c_str(), wall_s);
}

}  // namespace

int main(int argc, char** argv) {
  SimOptions options;
  std::string output;
  double fov_deg = options.laser.fov_deg;
  double encounter_fov_deg = options.encounters.field_of_view_deg;
  double rotation_noise_deg_per_sqrt_m =
      options.odometry.rotation_noise_rad_per_sqrt_m * kDegPerRad;
  unsigned long long seed = options.seed;
  bool quiet = false;
  std::string preview_png;

  // clang-format off
  po::options_description general("anchormap-sim: simulate robots, write an LCM log");
  general.add_options()
      ("help,h", "print this help and exit")
      ("robots", po::value(&options.robots)->default_value(options.robots),
       "number of robots R1..RN (1-1000)")
      ("seed", po::value(&seed)->default_value(seed),
       "random seed; equal seeds give byte-identical logs")
      ("duration-s", po::value(&options.duration_s)->default_value(options.duration_s),
       "simulated seconds")
      ("output", po::value(&output), "output LCM log file (required)")
      ("world", po::value(&options.world)->default_value(options.world),
       "'office' (built-in floor plan, 40x30 m tiles) or a PGM image / map_server YAML file")
      ("world-resolution-m",
       po::value(&options.world_resolution_m)->default_value(options.world_resolution_m),
       "metres per pixel of a .pgm world (a .yaml world has its own)")
      ("office-robots-per-tile",
       po::value(&options.office_robots_per_tile)->default_value(options.office_robots_per_tile),
       "the office grows by one 40x30 m tile per this many robots")
      ("preview-png", po::value(&preview_png),
       "also draw the walls, true paths and encounters into this PNG")
      ("quiet,q", po::bool_switch(&quiet), "print nothing on success");
  po::options_description sensors("Sensors");
  sensors.add_options()
      ("odometry-rate-hz", po::value(&options.odometry_rate_hz)->default_value(options.odometry_rate_hz),
       "odometry messages per second")
      ("laser-rate-hz", po::value(&options.laser.rate_hz)->default_value(options.laser.rate_hz),
       "laser scans (and ground-truth poses) per second")
      ("beams", po::value(&options.laser.beams)->default_value(options.laser.beams),
       "laser beams per scan")
      ("fov-deg", po::value(&fov_deg)->default_value(fov_deg),
       "laser field of view, centred on the heading")
      ("max-range-m", po::value(&options.laser.max_range_m)->default_value(options.laser.max_range_m),
       "laser range; no-return beams read this value")
      ("range-noise-m", po::value(&options.laser.range_noise_m)->default_value(options.laser.range_noise_m),
       "laser range noise (standard deviation)")
      ("dropout-probability",
       po::value(&options.laser.dropout_probability)->default_value(options.laser.dropout_probability),
       "chance that a beam returns nothing")
      ("odometry-translation-noise",
       po::value(&options.odometry.translation_noise_m_per_sqrt_m)
           ->default_value(options.odometry.translation_noise_m_per_sqrt_m),
       "odometry position error (std, m) after 1 m; grows with sqrt(distance)")
      ("odometry-rotation-noise-deg",
       po::value(&rotation_noise_deg_per_sqrt_m)->default_value(rotation_noise_deg_per_sqrt_m),
       "odometry heading error (std, deg) after 1 m; grows with sqrt(distance)")
      ("odometry-turn-noise",
       po::value(&options.odometry.rotation_noise_rad_per_sqrt_rad)
           ->default_value(options.odometry.rotation_noise_rad_per_sqrt_rad),
       "odometry heading error (std, rad) after turning 1 rad")
      ("odometry-scale-error",
       po::value(&options.odometry.scale_error_stddev)->default_value(options.odometry.scale_error_stddev),
       "std of each robot's constant distance scale error")
      ("encounter-range-m",
       po::value(&options.encounters.max_range_m)->default_value(options.encounters.max_range_m),
       "robots see each other up to this distance (with line of sight)")
      ("encounter-fov-deg", po::value(&encounter_fov_deg)->default_value(encounter_fov_deg),
       "robot detector field of view")
      ("encounter-period-s",
       po::value(&options.encounters.min_period_s)->default_value(options.encounters.min_period_s),
       "at most one encounter per ordered robot pair per period")
      ("encounter-sigma-xy-m",
       po::value(&options.encounters.sigma_xy_m)->default_value(options.encounters.sigma_xy_m),
       "encounter position noise (std)")
      ("encounter-sigma-theta-rad",
       po::value(&options.encounters.sigma_theta_rad)->default_value(options.encounters.sigma_theta_rad),
       "encounter heading noise (std)");
  po::options_description motion("Motion and routes");
  motion.add_options()
      ("speed-mps", po::value(&options.motion.speed_mps)->default_value(options.motion.speed_mps),
       "driving speed")
      ("turn-rate-radps",
       po::value(&options.motion.turn_rate_radps)->default_value(options.motion.turn_rate_radps),
       "turning speed in place")
      ("max-dwell-s", po::value(&options.motion.max_dwell_s)->default_value(options.motion.max_dwell_s),
       "longest pause at a destination")
      ("clearance-m", po::value(&options.planner.clearance_m)->default_value(options.planner.clearance_m),
       "smallest distance between a robot's centre and a wall")
      ("planner-resolution-m",
       po::value(&options.planner.resolution_m)->default_value(options.planner.resolution_m),
       "route planner grid cell size");
  // clang-format on
  po::options_description all;
  all.add(general).add(sensors).add(motion);

  po::variables_map vm;
  try {
    po::store(po::command_line_parser(argc, argv).options(all).run(), vm);
    po::notify(vm);
  } catch (const std::exception& e) {
    std::cerr << "anchormap-sim: " << e.what() << "\n(see --help)\n";
    return 2;
  }
  if (vm.count("help")) {
    std::cout << "Usage: anchormap-sim --robots N --seed S --duration-s T --output FILE.lcmlog "
                 "[--world office|FILE.pgm|FILE.yaml] [options]\n\n"
              << all << "\n";
    return 0;
  }
  if (output.empty()) {
    std::cerr << "anchormap-sim: --output is required (see --help)\n";
    return 2;
  }
  options.seed = seed;
  options.laser.fov_deg = fov_deg;
  options.encounters.field_of_view_deg = encounter_fov_deg;
  options.odometry.rotation_noise_rad_per_sqrt_m = rotation_noise_deg_per_sqrt_m / kDegPerRad;
  options.planner.preferred_clearance_m =
      std::max(options.planner.preferred_clearance_m, options.planner.clearance_m);
  if (const anchormap::Status valid = options.Validate(); !valid.ok()) {
    std::cerr << "anchormap-sim: " << valid.message() << "\n";
    return 2;
  }

  const auto start = std::chrono::steady_clock::now();
  anchormap::sim::SimSummary summary;
  anchormap::sim::SimTrace trace;
  const anchormap::Status status = anchormap::sim::WriteSimulationLog(
      options, output, &summary, preview_png.empty() ? nullptr : &trace);
  if (!status.ok()) {
    std::cerr << "anchormap-sim: " << status.message() << "\n";
    return 1;
  }
  if (!preview_png.empty()) {
    // The world again (cheap) for its walls; the log is already complete.
    std::unique_ptr<anchormap::sim::Simulator> simulator;
    anchormap::Status preview = anchormap::sim::Simulator::Create(options, &simulator);
    if (preview.ok())
      preview = anchormap::sim::WriteSimPreviewPng(simulator->world(), trace, preview_png);
    if (!preview.ok()) {
      std::cerr << "anchormap-sim: preview: " << preview.message() << "\n";
      return 1;
    }
  }
  const double wall_s =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  if (!quiet) PrintSummary(options, summary, output, wall_s);
  return 0;
}
