#pragma once
// A log-odds occupancy grid with unbounded extent, stored as square tiles that appear
// where scans reach (so the bounds grow as robots explore). Scans are inserted by tracing
// each beam from the sensor with Bresenham's line: cells passed through are "miss", the
// end cell of a return is "hit" (the inverse sensor model of Thrun et al., Probabilistic
// Robotics ch. 9, with clamped log-odds). Exported as tiles in the ROS convention (0..100,
// -1 unknown), which is what anchormap.grid_tile_t carries. The server rebuilds it from all
// keyframes at their current poses, since poses move after every solver update.

#include <cstdint>
#include <optional>
#include <string>
#include <unordered_map>
#include <utility>
#include <vector>

#include <Eigen/Core>

#include "common/geometry/pose2.h"
#include "common/types/laser_scan.h"
#include "common/types/map_outputs.h"
#include "common/util/status.h"

namespace anchormap {

struct OccupancyGridOptions {
  // Cell size. Smaller cells: sharper walls, quadratically more memory and ray cost.
  double resolution_m = 0.05;
  // Cells per tile side (tiles are the unit of growth and of publication).
  int tile_size_cells = 128;
  // Log-odds added per hit / per miss: ln(0.7/0.3) and ln(0.4/0.6).
  double log_odds_hit = 0.85;
  double log_odds_miss = -0.4;
  // Clamping keeps the map able to change its mind about moved obstacles.
  double log_odds_min = -2.0;
  double log_odds_max = 3.5;
  // Beams are traced at most this far; a return beyond it only clears cells up to here.
  double max_ray_length_m = 25.0;
  // Trace "no return" beams as free space up to max_ray_length_m (off: they carry no
  // information about where the free space ends, and glass or black surfaces give none).
  bool no_return_as_free = false;

  Status Validate() const;
};

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
  static uint64_t TileKey(int64_t tile_x, int64_t tile_y);
  void UpdateCell(int64_t cell_x, int64_t cell_y, double delta);

  OccupancyGridOptions options_;
  std::unordered_map<uint64_t, Tile> tiles_;
  // InsertScan's once-per-cell bookkeeping: a square window of cells around the sensor
  // (every traced cell falls inside it), stamped with the scan number instead of being
  // cleared per scan; `window_hit_` says whether the cell's update is a hit.
  std::vector<uint32_t> window_stamp_;
  std::vector<uint8_t> window_hit_;
  uint32_t scan_stamp_ = 0;
};

// The cells of the digital straight line from (x0, y0) to (x1, y1), both ends included
// (Bresenham). Exposed for tests.
std::vector<std::pair<int64_t, int64_t>> BresenhamLine(int64_t x0, int64_t y0, int64_t x1,
                                                       int64_t y1);

}  // namespace anchormap
