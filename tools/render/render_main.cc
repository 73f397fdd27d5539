// anchormap-render: turns the server's output LCM log into files people open without us:
// the merged map as PNG, PGM + YAML (ROS map_server) and g2o, and the anchors'
// uncertainty plot. See docs/TOOLS-SIM.md.

#include <cstdio>
#include <iostream>
#include <optional>
#include <set>
#include <string>

#include <boost/program_options.hpp>

#include "common/bus/authenticator.h"
#include "tools/render/map_export.h"
#include "tools/render/map_png.h"
#include "tools/render/merged_graph.h"
#include "tools/render/occupancy_raster.h"
#include "tools/render/server_output.h"
#include "tools/render/uncertainty_plot.h"

namespace po = boost::program_options;
using namespace anchormap::render;  // NOLINT: a tool's main

namespace {

ColorAssignment ColorsFor(const ServerOutput& output) {
  std::vector<TrajectoryKey> keys;
  if (output.map) {
    for (const TrajectoryView& t : output.map->trajectories) keys.push_back(t.key);
  }
  for (const AnchorSample& s : output.anchor_samples) keys.push_back(s.key);
  return ColorAssignment(std::move(keys));
}

void PrintSummary(const std::string& path, const ServerOutput& output,
                  const OccupancyRaster& raster) {
  std::printf("anchormap-render: %s\n", path.c_str());
  if (output.map) {
    std::printf("  merged map update %lld: %zu trajectories, %zu keyframes, %zu encounters",
                static_cast<long long>(output.map->update), output.map->trajectories.size(),
                output.map->NumPoses(), output.map->encounters.size());
    size_t anchored = 0;
    for (const TrajectoryView& t : output.map->trajectories) anchored += t.anchored ? 1 : 0;
    std::printf(" (%zu anchored)\n", anchored);
  } else {
    std::printf("  no merged map in the log\n");
  }
  if (!raster.empty()) {
    std::printf("  grid %d x %d cells at %.3f m (%zu tiles, update %lld", raster.width,
                raster.height, raster.resolution_m, output.grid.size(),
                static_cast<long long>(output.grid_update));
    if (output.grid_tiles_from_earlier_updates > 0) {
      std::printf(", %lld from earlier updates",
                  static_cast<long long>(output.grid_tiles_from_earlier_updates));
    }
    std::printf(")\n");
  } else {
    std::printf("  no grid tiles in the log\n");
  }
  if (output.status) {
    const ServerStatus& status = *output.status;
    std::printf(
        "  server status (update %lld): %d robots, %d trajectories (%d anchored), %lld keyframes, "
        "%lld encounters; rejected:",
        static_cast<long long>(status.update), status.num_robots, status.num_trajectories,
        status.num_anchored, static_cast<long long>(status.keyframes),
        static_cast<long long>(status.encounters));
    if (status.rejections.empty()) std::printf(" none");
    for (const auto& [reason, count] : status.rejections) {
      std::printf(" %s=%lld", reason.c_str(), static_cast<long long>(count));
    }
    std::printf("\n");
  }
  std::set<TrajectoryKey> anchors;
  for (const AnchorSample& s : output.anchor_samples) anchors.insert(s.key);
  std::printf("  %lld anchor-covariance messages (%zu anchors)\n",
              static_cast<long long>(output.covariance_messages), anchors.size());
  if (output.unauthenticated > 0) {
    std::printf("  refused by the key check: %lld messages (unsigned, unknown key or forged)\n",
                static_cast<long long>(output.unauthenticated));
  }
  if (output.undecodable > 0 || output.dangling_links > 0) {
    std::printf(
        "  skipped: %lld undecodable or invalid messages, %lld links to unknown keyframes\n",
        static_cast<long long>(output.undecodable), static_cast<long long>(output.dangling_links));
  }
}

}  // namespace

int main(int argc, char** argv) {
  std::string map_log, png, pgm, yaml, g2o, uncertainty_png;
  ChannelNames channels;
  MapPngOptions png_options;
  bool no_encounters = false;
  bool quiet = false;
  std::string key_file;
  po::options_description options("anchormap-render: render the server's output log");
  // clang-format off
  options.add_options()
      ("help,h", "print this help and exit")
      ("map", po::value(&map_log), "the server's output LCM log (required)")
      ("png", po::value(&png), "write the merged map (grid, trajectories, encounters) as PNG")
      ("pgm", po::value(&pgm), "write the occupancy grid as PGM, with a map_server YAML beside it")
      ("yaml", po::value(&yaml), "YAML path for --pgm (default: the PGM path with .yaml)")
      ("g2o", po::value(&g2o),
       "write the merged graph (keyframes, odometry chains, encounters) as g2o")
      ("uncertainty-png", po::value(&uncertainty_png),
       "plot every anchor's positional uncertainty over the updates")
      ("pixels-per-m", po::value(&png_options.pixels_per_m)->default_value(0.0),
       "map PNG scale (0: about 1400 px on the longer side)")
      ("no-encounters", po::bool_switch(&no_encounters), "do not draw encounter lines")
      ("title", po::value(&png_options.title)->default_value(png_options.title), "map PNG title")
      ("map-header-channel", po::value(&channels.map_header)->default_value(channels.map_header),
       "merged map header channel")
      ("map-chunks-channel", po::value(&channels.map_chunks)->default_value(channels.map_chunks),
       "merged map chunk channel")
      ("merged-map-channel", po::value(&channels.merged_map)->default_value(channels.merged_map),
       "merged map channel (logs of servers before the chunks)")
      ("grid-channel", po::value(&channels.grid_tiles)->default_value(channels.grid_tiles),
       "grid tile channel")
      ("covariance-channel",
       po::value(&channels.anchor_covariances)->default_value(channels.anchor_covariances),
       "anchor covariance channel")
      ("status-channel", po::value(&channels.server_status)->default_value(channels.server_status),
       "server status channel")
      ("key-file", po::value(&key_file), anchormap::kServerOutputKeyFileHelp)
      ("quiet,q", po::bool_switch(&quiet), "print only errors");
  // clang-format on
  po::variables_map vm;
  try {
    po::store(po::command_line_parser(argc, argv).options(options).run(), vm);
    po::notify(vm);
  } catch (const std::exception& e) {
    std::cerr << "anchormap-render: " << e.what() << "\n(see --help)\n";
    return 2;
  }
  if (vm.count("help")) {
    std::cout << "Usage: anchormap-render --map OUT.lcmlog [--png map.png] [--pgm map.pgm] "
                 "[--g2o merged.g2o] [--uncertainty-png anchors.png]\n\n"
              << options << "\n";
    return 0;
  }
  if (map_log.empty()) {
    std::cerr << "anchormap-render: --map is required (see --help)\n";
    return 2;
  }
  if (png.empty() && pgm.empty() && g2o.empty() && uncertainty_png.empty()) {
    std::cerr
        << "anchormap-render: nothing to write: give --png, --pgm, --g2o or --uncertainty-png\n";
    return 2;
  }
  if (!(png_options.pixels_per_m >= 0.0 && png_options.pixels_per_m <= 1000.0)) {
    std::cerr << "anchormap-render: --pixels-per-m must be in [0, 1000]\n";
    return 2;
  }
  png_options.draw_encounters = !no_encounters;

  std::optional<anchormap::Authenticator> authenticator;
  if (!key_file.empty()) {
    anchormap::AuthenticatorOptions checking;
    checking.sender = "render";  // (it never signs)
    anchormap::Result<anchormap::Authenticator> loaded =
        anchormap::LoadAuthenticator(key_file, checking);
    if (!loaded.ok()) {
      std::cerr << "anchormap-render: " << loaded.status().message() << "\n";
      return 1;
    }
    authenticator.emplace(std::move(*loaded));
  }
  ServerOutput output;
  if (anchormap::Status status =
          ReadServerOutput(map_log, channels, &output, authenticator ? &*authenticator : nullptr);
      !status.ok()) {
    std::cerr << "anchormap-render: " << status.message() << "\n";
    return 1;
  }
  int skipped_tiles = 0;
  const OccupancyRaster raster = AssembleGrid(output.grid, &skipped_tiles);
  if (!quiet) PrintSummary(map_log, output, raster);
  if (skipped_tiles > 0)
    std::cerr << "anchormap-render: skipped " << skipped_tiles << " grid tiles\n";
  const ColorAssignment colors = ColorsFor(output);

  int failures = 0;
  auto report = [&](const anchormap::Status& status, const std::string& what,
                    const std::string& path) {
    if (!status.ok()) {
      std::cerr << "anchormap-render: " << what << ": " << status.message() << "\n";
      ++failures;
    } else if (!quiet) {
      std::printf("  wrote %s %s\n", what.c_str(), path.c_str());
    }
  };
  if (!png.empty()) {
    MapViewport viewport;
    const anchormap::Status status = RenderMapPng(output.map ? &*output.map : nullptr, raster,
                                                  colors, png_options, png, &viewport);
    report(status,
           "map PNG (" + std::to_string(viewport.width_px) + " x " +
               std::to_string(viewport.height_px) + " px)",
           png);
  }
  if (!pgm.empty()) {
    const std::string yaml_path = yaml.empty() ? YamlPathFor(pgm) : yaml;
    report(WriteMapServerFiles(raster, pgm, yaml_path), "PGM + YAML", pgm + " " + yaml_path);
  }
  if (!g2o.empty()) {
    if (!output.map) {
      report(anchormap::Status::Error("no merged map in the log"), "g2o", g2o);
    } else {
      const anchormap::PoseGraph graph = BuildMergedGraph(*output.map);
      report(anchormap::WritePoseGraph(g2o, graph, anchormap::GraphFormat::kG2o),
             "g2o (" + std::to_string(graph.vertices.size()) + " vertices, " +
                 std::to_string(graph.edges.size()) + " edges)",
             g2o);
    }
  }
  if (!uncertainty_png.empty()) {
    report(RenderUncertaintyPlot(output.anchor_samples, colors, UncertaintyPlotOptions{},
                                 uncertainty_png),
           "uncertainty plot", uncertainty_png);
  }
  return failures == 0 ? 0 : 1;
}
