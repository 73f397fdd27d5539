#pragma once
// The occupancy grid as a ROS map_server map: PGM image (map_saver's trinary values: 254
// free, 0 occupied, 205 unknown) and a YAML file beside it naming the image, the
// resolution and the world position of the lower-left pixel.

#include <string>

#include "common/util/status.h"
#include "tools/render/occupancy_raster.h"

namespace anchormap::render {

// Writes `pgm_path` and `yaml_path`; the YAML names the image relative to its own folder.
Status WriteMapServerFiles(const OccupancyRaster& raster, const std::string& pgm_path,
                           const std::string& yaml_path);

// "map.pgm" -> "map.yaml" (same folder, extension replaced or appended).
std::string YamlPathFor(const std::string& pgm_path);

}  // namespace anchormap::render
