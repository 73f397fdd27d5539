#pragma once
// A floor plan from an occupancy image (ROS map_server convention): occupied pixels
// become walls (the borders between occupied and other pixels, merged into long
// segments), free pixels are where robots may drive, unknown pixels are neither.

#include <string>

#include "common/io/map_file.h"
#include "common/util/status.h"
#include "tools/sim/floor_plan.h"

namespace anchormap::sim {

// `path` is a .pgm image (then `resolution_m` applies, origin (0, 0)) or a map_server
// .yaml file (its own resolution, origin, negate and thresholds; yaw must be 0).
Status LoadPgmWorld(const std::string& path, double resolution_m, FloorPlan* plan);

// The same from an image already in memory.
FloorPlan FloorPlanFromImage(const GrayImage& image, const MapMetadata& metadata);

}  // namespace anchormap::sim
