#pragma once
// The merged map as a PNG: occupancy grid in grey levels (black occupied, white free,
// light grey unknown, a ramp between free and occupied), each trajectory as a line in its own
// colour (dashed when not yet anchored: it is then drawn in its own local frame), encounters as
// thin dark lines between the keyframes they join, a legend, a title and a scale bar.

#include <string>

#include <Eigen/Core>

#include "common/util/status.h"
#include "tools/render/colors.h"
#include "tools/render/occupancy_raster.h"
#include "tools/render/server_output.h"

namespace anchormap::render {

struct MapPngOptions {
  double pixels_per_m = 0.0;  // 0: chosen so that the longer side is about target_side_px
  double target_side_px = 1400.0;
  int max_side_px = 8000;  // never larger, whatever pixels_per_m says
  double margin_m = 2.0;   // space around the map content
  double trajectory_width_px = 2.0;
  bool draw_encounters = true;
  std::string title = "anchormap merged map";
};

// World (metres) to pixel mapping of a rendered map.
struct MapViewport {
  Eigen::Vector2d world_min{0.0, 0.0};
  Eigen::Vector2d world_max{1.0, 1.0};
  double pixels_per_m = 10.0;
  int header_px = 40;  // title band above the map
  int width_px = 0;
  int height_px = 0;
  Eigen::Vector2d ToPixel(const Eigen::Vector2d& world) const {
    return {(world.x() - world_min.x()) * pixels_per_m,
            header_px + (world_max.y() - world.y()) * pixels_per_m};
  }
};

// The viewport that shows `raster` and every pose of `map` (either may be empty).
MapViewport ChooseViewport(const MergedMap* map, const OccupancyRaster& raster,
                           const MapPngOptions& options);

// Draws and writes the PNG; `viewport` (optional) receives the mapping used.
Status RenderMapPng(const MergedMap* map, const OccupancyRaster& raster,
                    const ColorAssignment& colors, const MapPngOptions& options,
                    const std::string& path, MapViewport* viewport = nullptr);

// Grey value of an occupancy cell in the PNG: unknown (-1) 205, free (<= 19.6) 255,
// occupied (>= 65) 0, a linear ramp in between (map_saver's thresholds).
uint8_t OccupancyGray(int8_t occupancy);

}  // namespace anchormap::render
