#pragma once
// A log-odds occupancy grid with unbounded extent, stored as square tiles that appear
// where scans reach (so the bounds grow as robots explore). Scans are inserted by tracing
// each beam from the sensor with Bresenham's line: cells passed through are "miss", the
// end cell of a return is "hit" (the inverse sensor model of Thrun et al., Probabilistic
// Robotics ch. 9, with clamped log-odds). Exported as tiles in the ROS convention (0..100,
// -1 unknown), which is what anchormap.grid_tile_t carries. Log-odds are clamped after each
// update, so the order of the scans matters; the server keeps a KeyframeGrid instead
// (keyframe_grid.h), whose scans can be taken out again.

#include <cstdint>
#include <cstdlib>
#include <optional>
#include <string>
#include <unordered_map>
#include <utility>
#include <vector>

#include <Eigen/Core>

#include "common/geometry/pose2.h"
#include "common/scan/grid_cells.h"
#include "common/scan/scan_tracer.h"
#include "common/types/laser_scan.h"
#include "common/types/map_outputs.h"
#include "common/util/status.h"

namespace anchormap {

class OccupancyGrid {
 public:
  explicit OccupancyGrid(const OccupancyGridOptions& options = {});

  const OccupancyGridOptions& options() const { return options_; }

  // Inserts `scan` taken with the robot body at T_map_body (the scan's own T_body_sensor
  // places the sensor). Cost: O(beams x ray length in cells).
  void InsertScan(const LaserScan& scan, const Pose2& T_map_body);
  // Traces one ray between two points in map coordinates; `hit` marks the end cell.
  void InsertRay(const Eigen::Vector2d& from_map, const Eigen::Vector2d& to_map, bool hit);

  // The cell containing a map point (floor of coordinate / resolution).
  std::pair<int64_t, int64_t> CellOf(const Eigen::Vector2d& p_map) const;
  // Log-odds of a cell; nullopt when never observed.
  std::optional<double> LogOdds(int64_t cell_x, int64_t cell_y) const;
  // 0..100, or -1 when never observed.
  int8_t Occupancy(int64_t cell_x, int64_t cell_y) const;

  // Every tile with at least one observed cell, sorted by (tile_y, tile_x).
  std::vector<GridTile> Tiles(int64_t utime, int64_t update) const;
  size_t num_tiles() const { return tiles_.size(); }
  void Clear() { tiles_.clear(); }

 private:
  struct Tile {
    std::vector<float> log_odds;  // NaN = never observed
  };
  void UpdateCell(int64_t cell_x, int64_t cell_y, double delta);

  OccupancyGridOptions options_;
  std::unordered_map<uint64_t, Tile> tiles_;
  ScanTracer tracer_;
};

// Calls visit(x, y) for each cell of the digital straight line from (x0, y0) to (x1, y1),
// both ends included, in order (Bresenham). No list is built: tracing a scan's beams this
// way saves an allocation per beam (the server re-traces thousands of scans per grid).
template <typename Visit>
void ForEachBresenhamCell(int64_t x0, int64_t y0, int64_t x1, int64_t y1, Visit&& visit) {
  const int64_t dx = std::abs(x1 - x0), dy = -std::abs(y1 - y0);
  const int64_t sx = x0 < x1 ? 1 : -1, sy = y0 < y1 ? 1 : -1;
  int64_t error = dx + dy;
  while (true) {
    visit(x0, y0);
    if (x0 == x1 && y0 == y1) break;
    const int64_t e2 = 2 * error;
    if (e2 >= dy) {
      error += dy;
      x0 += sx;
    }
    if (e2 <= dx) {
      error += dx;
      y0 += sy;
    }
  }
}

// The same cells as a list. Exposed for tests.
std::vector<std::pair<int64_t, int64_t>> BresenhamLine(int64_t x0, int64_t y0, int64_t x1,
                                                       int64_t y1);

}  // namespace anchormap
