#pragma once
// A floor plan as the simulator consumes it: the walls, where robots may go, and the
// places (rooms, corridor junctions) that routes are built from. Made by the built-in
// office generator (office_plan.h) or from a PGM occupancy image (pgm_world.h).

#include <cstdint>
#include <vector>

#include <Eigen/Core>

#include "tools/sim/world.h"

namespace anchormap::sim {

struct Place {
  Eigen::Vector2d position{0.0, 0.0};  // world frame, metres
  int region = 0;                      // office tile index (0 in PGM worlds)
  bool is_room = false;                // rooms are start places; corridors are crossings
};

// Optional restriction of where robots may drive, on a raster (PGM worlds: only cells
// known to be free are traversable; unknown space is not a wall but is not entered).
struct TraversableMask {
  int width = 0;
  int height = 0;
  double resolution_m = 0.05;
  Eigen::Vector2d origin{0.0, 0.0};  // world position of the lower-left corner of cell (0, 0)
  std::vector<uint8_t> free;         // row-major, row 0 at the bottom; 1 = traversable

  bool empty() const { return free.empty(); }
  bool IsFree(const Eigen::Vector2d& point) const {
    const Eigen::Vector2d cell = (point - origin) / resolution_m;
    const int ix = static_cast<int>(cell.x() >= 0.0 ? cell.x() : -1.0);
    const int iy = static_cast<int>(cell.y() >= 0.0 ? cell.y() : -1.0);
    if (ix < 0 || iy < 0 || ix >= width || iy >= height) return false;
    return free[static_cast<size_t>(iy) * width + ix] != 0;
  }
};

struct FloorPlan {
  std::vector<WallSegment> walls;
  std::vector<Place> places;  // empty for PGM worlds: routes then sample free points
  TraversableMask mask;       // empty for the office: everywhere inside the walls
  int regions_x = 1;          // office tiles in x and y (region = ry * regions_x + rx)
  int regions_y = 1;
};

}  // namespace anchormap::sim
