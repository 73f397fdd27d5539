#pragma once
// What the occupancy grids share: their options (cell size, inverse sensor model), the
// numbering of cells and tiles, and the export of log-odds as ROS occupancy (0..100).

#include <cmath>
#include <cstdint>
#include <utility>

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

// Farther than this from the map's origin, a point has no cell (1e7 m at 5 cm is 2e8 cells).
inline constexpr double kMaxGridCoordinateM = 1e7;

// Floor of a / b for b > 0 (cell -> tile index for negative cells too).
inline int64_t FloorDiv(int64_t a, int64_t b) {
  int64_t q = a / b;
  if ((a % b != 0) && ((a < 0) != (b < 0))) --q;
  return q;
}

// One 64-bit key per tile (tile indices fit in 32 bits within kMaxGridCoordinateM).
inline uint64_t TileKey(int64_t tile_x, int64_t tile_y) {
  return (static_cast<uint64_t>(static_cast<uint32_t>(tile_x)) << 32) |
         static_cast<uint64_t>(static_cast<uint32_t>(tile_y));
}
inline std::pair<int32_t, int32_t> TileOfKey(uint64_t key) {
  return {static_cast<int32_t>(static_cast<uint32_t>(key >> 32)),
          static_cast<int32_t>(static_cast<uint32_t>(key & 0xffffffffu))};
}

// Probability 0..100 of a log-odds value (ROS map convention).
inline int8_t OccupancyFromLogOdds(double log_odds) {
  const double p = 1.0 - 1.0 / (1.0 + std::exp(log_odds));
  return static_cast<int8_t>(std::lround(100.0 * p));
}

}  // namespace anchormap
