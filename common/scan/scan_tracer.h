#pragma once
// The cells one laser scan observes: each beam traced from the sensor with Bresenham's
// line, cells passed through are misses, the end cell of a return within the ray length
// is a hit. Each cell is reported once per scan (a hit wins over a miss), so that the beam
// density near the sensor does not count as repeated evidence. Deterministic: the same
// scan at the same pose gives the same cells, which lets a grid take a scan out again.

#include <algorithm>
#include <cstdint>
#include <cstdlib>
#include <cstring>
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
  // MarkCells walks every beam once; ForEachMarkedRow then calls row(wy, first, last, marks)
  // for each window row wy holding traced cells, all of them within [first, last] (whole
  // groups of kMarkGroup cells, each group's first cell's map x a multiple of kMarkGroup), where
  // marks[wx] (first <= wx <= last) is kHitMark for the cell (min_x + wx, min_y + wy) traced
  // as a hit, kMissMark for a miss, 0 for a cell not traced; and clears those marks again.
  // Before it, ForEachHit may call hit(wx, wy) once per cell traced as a hit (at most one
  // per beam: a caller may count them apart from the rows' misses).
  static constexpr uint8_t kMissMark = 1, kHitMark = 2;
  static constexpr int64_t kMarkGroup = 16;
  bool MarksInWindow() const { return use_window_; }
  void MarkCells();
  template <typename Hit>
  void ForEachHit(Hit&& hit);
  template <typename Row>
  void ForEachMarkedRow(Row&& row);

  // A scan moved from T_map_from to T_map_to as two traces in one window, so that a grid
  // reads and writes the rows' counts once for both (taking a scan out at its old pose and
  // in at its new one was ~4/5 of the server grid's work at 100 robots). StartMove returns
  // the window, or nullopt when the move is not one (either trace has no cells, or the
  // sensor moved more than kMoveSlack cells along x or y: a pass over the union of the two
  // traces' rows then nears the cost of two passes, for the server's 25 m rays at 5 cm);
  // the window holds both traces' cells, each as Start would report them. Only when
  // MarksInWindow(): MarkMove marks both traces, each in its own marks; ForEachMoveHit calls
  // hit(wx, wy, in) once per hit cell of the trace out (in false) and of the trace in (in
  // true); ForEachMoveRow calls row(wy, first, last, out, in) for each row either trace
  // holds cells in, [first, last] (aligned as ForEachMarkedRow's) holding every traced cell
  // of both, out[wx] and in[wx] the two traces' marks as ForEachMarkedRow's marks; and
  // clears them.
  // 12.8 m at 5 cm: 74 % of the moves of a 100 x 180 replay (22 % moved 25 m or more, their
  // trajectories anchored anew).
  static constexpr int64_t kMoveSlack = 256;
  std::optional<Window> StartMove(const LaserScan& scan, const Pose2& T_map_from,
                                  const Pose2& T_map_to, const OccupancyGridOptions& options);
  void MarkMove();
  template <typename Hit>
  void ForEachMoveHit(Hit&& hit);
  template <typename Row>
  void ForEachMoveRow(Row&& row);

 private:
  struct BeamEnd {
    int64_t wx, wy;
    bool hit;  // the end of a return within the ray length
  };
  // One trace's beams: the sensor's cell and the beams' end cells, in window coordinates.
  struct Beams {
    int64_t sensor_wx = 0, sensor_wy = 0;
    std::vector<BeamEnd> ends;
  };
  // MarkCells' marks of one trace: one byte per window cell, zero outside a trace
  // (ForEachMarkedRow clears what it reports, so a trace writes only the cells of its beams
  // and no stamp needs reading). The traced rows are first_row..last_row (the beams' ends'
  // rows and the sensor's: each beam crosses every row between); row wy's cells lie within
  // reach[0][wy] cells left of the sensor's column x0 and reach[1][wy] right of it (the
  // farthest any beam on that side reaches in the row; zero outside a trace).
  struct Marks {
    std::vector<uint8_t> cells;
    std::vector<int16_t> reach[2];
    int64_t first_row = 0, last_row = -1, x0 = 0;
    bool dirty = false;
    // Row wy's extent, whole aligned groups (the window's first column is aligned).
    int64_t First(int64_t wy) const { return (x0 - reach[0][wy]) / kMarkGroup * kMarkGroup; }
    int64_t Last(int64_t wy) const {
      return (x0 + reach[1][wy]) / kMarkGroup * kMarkGroup + kMarkGroup - 1;
    }
    // Zeroes row wy's marks and reach.
    void ClearRow(int64_t wy, int64_t side, int64_t first, int64_t last) {
      uint8_t* const row = cells.data() + wy * side;
      constexpr uint64_t kZero = 0;
      for (int64_t x = first; x <= last; x += 8) std::memcpy(row + x, &kZero, 8);
      reach[0][wy] = reach[1][wy] = 0;
    }
  };
  // The window around the sensor's cell (x0, y0) (Start); false when T_map_sensor has no cells.
  bool SensorCell(const Pose2& T_map_sensor, const OccupancyGridOptions& options, int64_t* x0,
                  int64_t* y0) const;
  // The end cells of `scan`'s beams from T_map_sensor into `beams` (window coordinates).
  void EndCells(const LaserScan& scan, const Pose2& T_map_sensor,
                const OccupancyGridOptions& options, Beams* beams);
  // Marks `beams`' cells in `marks` (cleared first when a trace left them unread).
  void MarkBeams(const Beams& beams, Marks* marks);
  template <typename Hit>
  void ForEachHitOf(const Beams& beams, Marks* marks, Hit&& hit);
  // Calls step(wx, wy, index) for each cell of the line from the sensor to `end`, both
  // included, with index = wy * side + wx: Bresenham's line as ForEachBresenhamCell
  // (occupancy_grid.h) draws it, the same cells in the same order.
  template <typename Step>
  void Walk(const BeamEnd& end, Step&& step) const;

  // VisitCells' de-duplication, prepared for the scan Start took.
  void PrepareStamps();
  // Zeroes the marks a trace left (when the caller did not read them).
  void ClearMarks(Marks* marks);

  Window window_;
  // [0]: Start's trace, or a move's trace out; [1]: a move's trace in.
  Beams beams_[2];
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
  // The marks of beams_[0] and beams_[1].
  Marks marks_[2];
  // Per row, of the beam being walked and of the one before (merged after the next walk).
  std::vector<int16_t> beam_reach_[2];
  std::unordered_map<uint64_t, uint8_t> far_cells_;
  std::vector<TracedCell> cells_;
};

// The farthest any beam of `scan` reaches from the sensor when traced with `options` (m):
// how far a rotation of the scan moves its cells.
double ScanReach(const LaserScan& scan, const OccupancyGridOptions& options);

template <typename Step>
void ScanTracer::Walk(const BeamEnd& end, Step&& step) const {
  const int64_t side = window_.side;
  int64_t x = beams_[0].sensor_wx, y = beams_[0].sensor_wy;
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
      error += dx;
      y += sy;
      index += step_y;
    }
  }
}

template <typename Visit>
void ScanTracer::VisitCells(Visit&& visit) {
  PrepareStamps();
  if (use_window_) {
    uint16_t* const stamps = stamps_.data();
    const uint16_t hit_stamp = hit_stamp_, visited_stamp = visited_stamp_;
    for (const BeamEnd& end : beams_[0].ends) {
      Walk(end, [&](int64_t x, int64_t y, int64_t index) {
        uint16_t& stamp = stamps[index];
        if (stamp == visited_stamp) return;
        const bool hit = stamp == hit_stamp;
        stamp = visited_stamp;
        visit(x, y, hit);
      });
    }
    return;
  }
  for (const BeamEnd& end : beams_[0].ends) {
    Walk(end, [&](int64_t x, int64_t y, int64_t) {
      auto [it, inserted] = far_cells_.try_emplace(TileKey(x, y), 0);
      if (it->second == 2) return;
      const bool hit = it->second == 1;
      it->second = 2;
      visit(x, y, hit);
    });
  }
}

template <typename Hit>
void ScanTracer::ForEachHitOf(const Beams& beams, Marks* marks, Hit&& hit) {
  // Several beams may end in one cell: its mark is changed at the first, and restored after.
  constexpr uint8_t kReported = kHitMark | 0x80;
  const int64_t side = window_.side;
  uint8_t* const cells = marks->cells.data();
  for (const BeamEnd& end : beams.ends) {
    uint8_t& mark = cells[static_cast<size_t>(end.wy * side + end.wx)];
    if (!end.hit || mark != kHitMark) continue;
    hit(end.wx, end.wy);
    mark = kReported;
  }
  for (const BeamEnd& end : beams.ends) {
    if (end.hit) cells[static_cast<size_t>(end.wy * side + end.wx)] = kHitMark;
  }
}

template <typename Hit>
void ScanTracer::ForEachHit(Hit&& hit) {
  ForEachHitOf(beams_[0], &marks_[0], hit);
}

template <typename Hit>
void ScanTracer::ForEachMoveHit(Hit&& hit) {
  ForEachHitOf(beams_[0], &marks_[0], [&](int64_t wx, int64_t wy) { hit(wx, wy, false); });
  ForEachHitOf(beams_[1], &marks_[1], [&](int64_t wx, int64_t wy) { hit(wx, wy, true); });
}

template <typename Row>
void ScanTracer::ForEachMarkedRow(Row&& row) {
  const int64_t side = window_.side;
  Marks& marks = marks_[0];
  for (int64_t wy = marks.first_row; wy <= marks.last_row; ++wy) {
    const int64_t first = marks.First(wy), last = marks.Last(wy);
    row(wy, first, last, static_cast<const uint8_t*>(marks.cells.data() + wy * side));
    marks.ClearRow(wy, side, first, last);
  }
  marks.dirty = false;
}

template <typename Row>
void ScanTracer::ForEachMoveRow(Row&& row) {
  const int64_t side = window_.side;
  Marks& out = marks_[0];
  Marks& in = marks_[1];
  for (int64_t wy = std::min(out.first_row, in.first_row);
       wy <= std::max(out.last_row, in.last_row); ++wy) {
    const bool has_out = out.first_row <= wy && wy <= out.last_row;
    const bool has_in = in.first_row <= wy && wy <= in.last_row;
    if (!has_out && !has_in) continue;  // a gap between the two traces' rows
    const int64_t first = std::min(has_out ? out.First(wy) : side, has_in ? in.First(wy) : side);
    const int64_t last = std::max(has_out ? out.Last(wy) : -1, has_in ? in.Last(wy) : -1);
    row(wy, first, last, static_cast<const uint8_t*>(out.cells.data() + wy * side),
        static_cast<const uint8_t*>(in.cells.data() + wy * side));
    out.ClearRow(wy, side, first, last);
    in.ClearRow(wy, side, first, last);
  }
  out.dirty = in.dirty = false;
}

}  // namespace anchormap
