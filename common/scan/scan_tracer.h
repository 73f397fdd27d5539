#pragma once
// The cells one laser scan observes: each beam traced from the sensor with Bresenham's
// line, cells passed through are misses, the end cell of a return within the ray length
// is a hit. Each cell is reported once per scan (a hit wins over a miss), so that the beam
// density near the sensor does not count as repeated evidence. Deterministic: the same
// scan at the same pose gives the same cells, which lets a grid take a scan out again.

#include <cstdint>
#include <cstdlib>
#include <optional>
#include <unordered_map>
#include <vector>

#include "common/geometry/pose2.h"
#include "common/scan/grid_cells.h"
#include "common/types/laser_scan.h"

namespace anchormap {

struct TracedCell {
  int64_t x = 0;
  int64_t y = 0;
  bool hit = false;
};

class ScanTracer {
 public:
  // The cells of `scan` taken with the robot body at T_map_body (the scan's T_body_sensor
  // places the sensor). Empty when the pose is not finite or absurdly far away (its cell
  // numbers would overflow). The reference stays valid until the next call.
  const std::vector<TracedCell>& Trace(const LaserScan& scan, const Pose2& T_map_body,
                                       const OccupancyGridOptions& options);

  // The same cells without a list, for a caller that adds them up (the server's grid
  // traces thousands of scans per publication): Start computes the beams' end cells and
  // returns the square every cell of the trace lies in (nullopt: no cells); VisitCells then
  // calls visit(wx, wy, hit) once per cell, with the cell (min_x + wx, min_y + wy),
  // 0 <= wx, wy < side, and its final hit flag.
  struct Window {
    int64_t min_x = 0;
    int64_t min_y = 0;
    int64_t side = 0;
  };
  std::optional<Window> Start(const LaserScan& scan, const Pose2& T_map_body,
                              const OccupancyGridOptions& options);
  template <typename Visit>
  void VisitCells(Visit&& visit);

  // The same cells left as marks in the window, for a caller that adds up whole rows (the
  // server's grid: its counts are then written along rows, not along the beams, whose steps
  // jump a row of cells at a time). Only when Start returned a window and MarksInWindow():
  // MarkCells walks every beam once; then a cell (min_x + wx, min_y + wy) was traced when
  // its mark, marks()[wy * side + wx], is hit_mark() (a hit) or hit_mark() + 1 (a miss),
  // and the traced cells of row wy lie within [row_min()[wy], row_max()[wy]] (empty when
  // min > max). The marks stay valid until the next Start.
  bool MarksInWindow() const { return use_window_; }
  void MarkCells();
  const uint16_t* marks() const { return stamps_.data(); }
  uint16_t hit_mark() const { return hit_stamp_; }
  const int32_t* row_min() const { return row_min_.data(); }
  const int32_t* row_max() const { return row_max_.data(); }

 private:
  // Calls step(wx, wy, index) for each cell of the line from the sensor to `end`, both
  // included, with index = wy * side + wx: Bresenham's line as ForEachBresenhamCell
  // (occupancy_grid.h) draws it, the same cells in the same order; and next_row(wx, wy,
  // next_wy) at each step to the next row, wx the column of the step's next cell.
  struct BeamEnd {
    int64_t wx, wy;
  };
  template <typename Step, typename NextRow>
  void Walk(const BeamEnd& end, Step&& step, NextRow&& next_row) const;

  Window window_;
  int64_t sensor_wx_ = 0, sensor_wy_ = 0;
  std::vector<BeamEnd> ends_;
  std::vector<Eigen::Vector2d> directions_;  // per beam, for the scan geometry below
  float directions_rad0_ = 0.0f, directions_radstep_ = 0.0f;
  // Cells are de-duplicated in the window around the sensor stamped per scan instead of
  // being cleared per scan (sorting the traced cells cost 40 % of a 10-robot server run):
  // a cell holding hit_stamp_ is the end of a return not visited yet, visited_stamp_ a
  // visited one. Rays too long for a window (side > kMaxWindowSide) use a hash map with
  // the same two marks instead.
  static constexpr int64_t kMaxWindowSide = 2049;
  bool use_window_ = false;
  std::vector<uint16_t> stamps_;
  uint16_t hit_stamp_ = 0, visited_stamp_ = 0;
  std::vector<int32_t> row_min_, row_max_;  // MarkCells' rows' extents
  std::unordered_map<uint64_t, uint8_t> far_cells_;
  std::vector<TracedCell> cells_;
};

// The farthest any beam of `scan` reaches from the sensor when traced with `options` (m):
// how far a rotation of the scan moves its cells.
double ScanReach(const LaserScan& scan, const OccupancyGridOptions& options);

template <typename Step, typename NextRow>
void ScanTracer::Walk(const BeamEnd& end, Step&& step, NextRow&& next_row) const {
  const int64_t side = window_.side;
  int64_t x = sensor_wx_, y = sensor_wy_;
  const int64_t dx = std::abs(end.wx - x), dy = -std::abs(end.wy - y);
  const int64_t sx = x < end.wx ? 1 : -1, sy = y < end.wy ? 1 : -1;
  const int64_t step_y = sy * side;
  int64_t index = y * side + x;
  const int64_t end_index = end.wy * side + end.wx;
  int64_t error = dx + dy;
  while (true) {
    step(x, y, index);
    if (index == end_index) break;
    const int64_t e2 = 2 * error;
    if (e2 >= dy) {
      error += dy;
      x += sx;
      index += sx;
    }
    if (e2 <= dx) {
      next_row(x, y, y + sy);
      error += dx;
      y += sy;
      index += step_y;
    }
  }
}

template <typename Visit>
void ScanTracer::VisitCells(Visit&& visit) {
  if (use_window_) {
    uint16_t* const stamps = stamps_.data();
    const uint16_t hit_stamp = hit_stamp_, visited_stamp = visited_stamp_;
    for (const BeamEnd& end : ends_) {
      Walk(
          end,
          [&](int64_t x, int64_t y, int64_t index) {
            uint16_t& stamp = stamps[index];
            if (stamp == visited_stamp) return;
            const bool hit = stamp == hit_stamp;
            stamp = visited_stamp;
            visit(x, y, hit);
          },
          [](int64_t, int64_t, int64_t) {});
    }
    return;
  }
  for (const BeamEnd& end : ends_) {
    Walk(
        end,
        [&](int64_t x, int64_t y, int64_t) {
          auto [it, inserted] = far_cells_.try_emplace(TileKey(x, y), 0);
          if (it->second == 2) return;
          const bool hit = it->second == 1;
          it->second = 2;
          visit(x, y, hit);
        },
        [](int64_t, int64_t, int64_t) {});
  }
}

}  // namespace anchormap
