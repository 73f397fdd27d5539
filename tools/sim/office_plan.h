#pragma once
// The built-in office floor plan: 40 m x 30 m tiles, each with a ring corridor (2.5 m
// wide) around a central block of four rooms split by a cross corridor, and fourteen rooms
// around the ring; every room has a 1.6 m door. Robots driving around the ring in
// different directions meet head-on, which is what makes encounters frequent.
//
// For many robots the tile is repeated on a grid; neighbouring tiles connect through doors
// in their shared outer walls, so the world stays one connected building. Each tile draws
// from the seed where its rooms' doors sit along their walls, furniture in room corners
// and cabinets along the ring corridor, so that no tile is an exact copy of another or of
// its own half-turn (an exact lattice is ambiguous by construction: no scan can tell the
// copies apart).

#include <cstdint>
#include <string>

#include "common/util/status.h"
#include "tools/sim/floor_plan.h"

namespace anchormap::sim {

struct OfficePlanOptions {
  int tiles_x = 1;            // tiles side by side in x
  int tiles_y = 1;            // tiles in y
  double door_width_m = 1.6;  // every door; must exceed twice the robots' clearance
  uint64_t seed = 1;          // draws each tile's variation (the simulator's seed)
  bool varied_tiles = true;   // false: every tile the same bare plan (layout tests)

  // Empty when valid, else the reason.
  Status Validate() const;
};

constexpr double kOfficeTileWidthM = 40.0;
constexpr double kOfficeTileHeightM = 30.0;

FloorPlan BuildOfficePlan(const OfficePlanOptions& options);

// Tiles for `num_robots` robots at `robots_per_tile`, arranged as close to square as the
// tile shape allows (tiles_x >= tiles_y).
OfficePlanOptions OfficeTilesForRobots(int num_robots, int robots_per_tile);

}  // namespace anchormap::sim
