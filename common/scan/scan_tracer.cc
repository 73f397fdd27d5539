#include "common/scan/scan_tracer.h"

#include <algorithm>
#include <cmath>
#include <tuple>

namespace anchormap {
namespace {

std::pair<int64_t, int64_t> Cell(const Eigen::Vector2d& p_map, double resolution_m) {
  return {static_cast<int64_t>(std::floor(p_map.x() / resolution_m)),
          static_cast<int64_t>(std::floor(p_map.y() / resolution_m))};
}

}  // namespace

const std::vector<TracedCell>& ScanTracer::Trace(const LaserScan& scan, const Pose2& T_map_body,
                                                 const OccupancyGridOptions& options) {
  cells_.clear();
  const std::optional<Window> window = Start(scan, T_map_body, options);
  if (!window) return cells_;
  VisitCells([&, min_x = window->min_x, min_y = window->min_y](int64_t x, int64_t y, bool hit) {
    cells_.push_back({min_x + x, min_y + y, hit});
  });
  return cells_;
}

bool ScanTracer::SensorCell(const Pose2& T_map_sensor, const OccupancyGridOptions& options,
                            int64_t* x0, int64_t* y0) const {
  const Eigen::Vector2d origin = T_map_sensor.translation();
  // A pose that is not finite, or absurdly far away, has no cells (the fuzzer fed one
  // through the server).
  if (!T_map_sensor.IsFinite() || origin.cwiseAbs().maxCoeff() > kMaxGridCoordinateM) {
    return false;
  }
  std::tie(*x0, *y0) = Cell(origin, options.resolution_m);
  return true;
}

std::optional<ScanTracer::Window> ScanTracer::Start(const LaserScan& scan, const Pose2& T_map_body,
                                                    const OccupancyGridOptions& options) {
  beams_[0].ends.clear();
  const Pose2 T_map_sensor = Compose(T_map_body, scan.T_body_sensor);
  int64_t x0 = 0, y0 = 0;
  if (!SensorCell(T_map_sensor, options, &x0, &y0)) return std::nullopt;
  // Every traced cell lies within `radius` of the sensor's cell (rays end within
  // max_ray_length_m); the window reaches kMoveSlack cells farther, so that a move's trace in
  // fits in its trace out's window (StartMove).
  const int64_t radius =
      static_cast<int64_t>(std::ceil(options.max_ray_length_m / options.resolution_m)) + 2;
  const int64_t reach = radius + kMoveSlack;
  // The window's columns start at a multiple of kMarkGroup in map coordinates and its side
  // is a multiple of it, so that MarkCells' rows come in whole aligned groups.
  const int64_t min_x = FloorDiv(x0 - reach, kMarkGroup) * kMarkGroup;
  // A side of a multiple of 64 (1024 for the server's 25 m at 5 cm) would put a beam's steps
  // from row to row in few cache sets: one more group then.
  int64_t side = (2 * reach + 2 * kMarkGroup - 1) / kMarkGroup * kMarkGroup;
  if (side % 64 == 0) side += kMarkGroup;
  window_ = {min_x, y0 - reach, side};
  // The window costs 2 bytes a cell in VisitCells' stamps: rays of up to 1024 cells.
  use_window_ = 2 * radius + 1 <= kMaxWindowSide;
  EndCells(scan, T_map_sensor, options, &beams_[0]);
  return window_;
}

std::optional<ScanTracer::Window> ScanTracer::StartMove(const LaserScan& scan,
                                                        const Pose2& T_map_from,
                                                        const Pose2& T_map_to,
                                                        const OccupancyGridOptions& options) {
  const Pose2 T_map_to_sensor = Compose(T_map_to, scan.T_body_sensor);
  int64_t x1 = 0, y1 = 0;
  if (!SensorCell(T_map_to_sensor, options, &x1, &y1)) return std::nullopt;
  const std::optional<Window> window = Start(scan, T_map_from, options);
  if (!window) return std::nullopt;
  const int64_t x0 = window->min_x + beams_[0].sensor_wx, y0 = window->min_y + beams_[0].sensor_wy;
  if (std::abs(x1 - x0) > kMoveSlack || std::abs(y1 - y0) > kMoveSlack) return std::nullopt;
  EndCells(scan, T_map_to_sensor, options, &beams_[1]);
  return window;
}

void ScanTracer::EndCells(const LaserScan& scan, const Pose2& T_map_sensor,
                          const OccupancyGridOptions& options, Beams* beams) {
  const auto [x0, y0] = Cell(T_map_sensor.translation(), options.resolution_m);
  beams->sensor_wx = x0 - window_.min_x;
  beams->sensor_wy = y0 - window_.min_y;
  beams->ends.clear();
  // The beams' end cells, and whether each is the end of a return within the ray length.
  auto end = [&](const Eigen::Vector2d& p_map, bool hit) {
    const auto [x1, y1] = Cell(p_map, options.resolution_m);
    beams->ends.push_back({x1 - window_.min_x, y1 - window_.min_y, hit});
  };
  // The beams' directions in the sensor frame, computed again only when the scan's geometry
  // changes (a team's scans share one): the same values as per beam.
  if (scan.ranges.size() != directions_.size() || scan.rad0 != directions_rad0_ ||
      scan.radstep != directions_radstep_) {
    directions_.resize(scan.ranges.size());
    for (size_t i = 0; i < scan.ranges.size(); ++i) {
      const double angle = scan.Angle(i);
      directions_[i] = Eigen::Vector2d(std::cos(angle), std::sin(angle));
    }
    directions_rad0_ = scan.rad0;
    directions_radstep_ = scan.radstep;
  }
  for (size_t i = 0; i < scan.ranges.size(); ++i) {
    const Eigen::Vector2d& direction = directions_[i];
    if (scan.IsReturn(i)) {
      const double range = scan.ranges[i];
      const double length = std::min<double>(range, options.max_ray_length_m);
      end(T_map_sensor.TransformPoint(length * direction), range <= options.max_ray_length_m);
    } else if (options.no_return_as_free) {
      end(T_map_sensor.TransformPoint(options.max_ray_length_m * direction), false);
    }
  }
}

void ScanTracer::PrepareStamps() {
  // The ends of returns within the ray length are marked as hits first, so that each cell
  // is reported once, with its final flag.
  if (use_window_) {
    const int64_t side = window_.side;
    if (stamps_.size() != static_cast<size_t>(side * side) || visited_stamp_ >= 0xfffe) {
      stamps_.assign(static_cast<size_t>(side * side), 0);  // new size, or every stamp used
      visited_stamp_ = 0;
    }
    hit_stamp_ = static_cast<uint16_t>(visited_stamp_ + 1);
    visited_stamp_ = static_cast<uint16_t>(visited_stamp_ + 2);
    for (const BeamEnd& end : beams_[0].ends) {
      if (end.hit) stamps_[static_cast<size_t>(end.wy * side + end.wx)] = hit_stamp_;
    }
  } else {
    far_cells_.clear();
    for (const BeamEnd& end : beams_[0].ends) {
      if (end.hit) far_cells_[TileKey(end.wx, end.wy)] = 1;
    }
  }
}

void ScanTracer::ClearMarks(Marks* marks) {
  for (int64_t wy = marks->first_row; wy <= marks->last_row; ++wy) {
    marks->ClearRow(wy, window_.side, marks->First(wy), marks->Last(wy));
  }
  marks->dirty = false;
}

void ScanTracer::MarkCells() { MarkBeams(beams_[0], &marks_[0]); }

void ScanTracer::MarkMove() {
  MarkBeams(beams_[0], &marks_[0]);
  MarkBeams(beams_[1], &marks_[1]);
}

void ScanTracer::MarkBeams(const Beams& beams, Marks* set) {
  const int64_t side = window_.side;
  if (set->cells.size() != static_cast<size_t>(side * side)) {
    set->cells.assign(static_cast<size_t>(side * side), 0);
    for (auto& reach : set->reach) reach.assign(static_cast<size_t>(side), 0);
    set->dirty = false;
  } else if (set->dirty) {
    ClearMarks(set);
  }
  for (auto& buffer : beam_reach_) {
    if (buffer.size() != static_cast<size_t>(side)) buffer.assign(static_cast<size_t>(side), 0);
  }
  uint8_t* const marks = set->cells.data();
  const int64_t x0 = beams.sensor_wx, y0 = beams.sensor_wy;
  int64_t first_row = y0, last_row = y0;
  set->x0 = x0;
  // Bresenham's line as ForEachBresenhamCell draws it, in closed form: along the major axis
  // (the one with the larger |d|) every step moves one cell, and after k steps the minor
  // axis has moved m_k = floor(k * minor / major + 1/2) cells (what the line's error term
  // gives, ties rounded up). m_k is computed in 32.32 fixed point with the slope rounded up:
  // the sum exceeds k * minor / major + 1/2 by less than k * 2^-32 <= 2^-21, below the
  // 1 / (2 * major) >= 2^-13 between it and any larger integer, so the floor is exact; and no
  // step waits on the last one's comparison (an error term's branches were mispredicted,
  // its masks one long chain). A cell is marked a miss by a plain store (the hits are marked
  // after every beam: a hit wins); the beam's reach from the sensor's column in each row it
  // crosses (its cells' x moves away from the sensor's monotonically, so the row's last step
  // holds it) is stored per step, then merged into the rows' reach on the beam's side in one
  // pass over its rows. That pass runs after the next beam's walk (two buffers, used in
  // turn): its vector loads right after the walk's 16-bit stores could not be forwarded from
  // them and waited for the stores (a fifth of this function's samples at 100 robots).
  struct Pending {
    const int16_t* beam_reach = nullptr;
    int16_t* reach = nullptr;
    int64_t from = 0, to = -1;
  } pending;
  auto merge = [](const Pending& p) {
    for (int64_t r = p.from; r <= p.to; ++r) p.reach[r] = std::max(p.reach[r], p.beam_reach[r]);
  };
  size_t buffer = 0;
  for (const BeamEnd& end : beams.ends) {
    int16_t* const beam_reach = beam_reach_[buffer].data();
    buffer ^= 1;
    const int64_t dx = std::abs(end.wx - x0), dy = std::abs(end.wy - y0);
    const int64_t sx = x0 < end.wx ? 1 : -1, sy = y0 < end.wy ? 1 : -1;
    const int64_t step_y = sy * side;
    uint8_t* const start = marks + y0 * side + x0;
    const int64_t major = std::max(dx, dy), minor = std::min(dx, dy);
    // major >= 1 below (a zero-length beam marks the sensor's cell only).
    const uint64_t slope =
        major == 0 ? 0 : ((static_cast<uint64_t>(minor) << 32) + major - 1) / major;
    uint64_t sum = uint64_t{1} << 31;
    if (dx >= dy) {
      int16_t* const reach_row = beam_reach + y0;
      for (int64_t k = 0; k <= major; ++k, sum += slope) {
        const int64_t m = static_cast<int64_t>(sum >> 32);
        start[sx * k + m * step_y] = kMissMark;
        reach_row[sy * m] = static_cast<int16_t>(k);
      }
    } else {
      for (int64_t k = 0; k <= major; ++k, sum += slope) {
        const int64_t m = static_cast<int64_t>(sum >> 32);
        start[k * step_y + sx * m] = kMissMark;
        beam_reach[y0 + sy * k] = static_cast<int16_t>(m);
      }
    }
    merge(pending);
    pending = {beam_reach, set->reach[sx > 0 ? 1 : 0].data(), std::min(y0, end.wy),
               std::max(y0, end.wy)};
    first_row = std::min(first_row, pending.from);
    last_row = std::max(last_row, pending.to);
  }
  merge(pending);
  for (const BeamEnd& end : beams.ends) {
    if (end.hit) marks[end.wy * side + end.wx] = kHitMark;
  }
  set->first_row = first_row;
  set->last_row = last_row;
  set->dirty = true;
}

double ScanReach(const LaserScan& scan, const OccupancyGridOptions& options) {
  double reach = 0.0;
  for (size_t i = 0; i < scan.ranges.size(); ++i) {
    if (scan.IsReturn(i)) {
      reach = std::max(reach, std::min<double>(scan.ranges[i], options.max_ray_length_m));
    } else if (options.no_return_as_free) {
      reach = options.max_ray_length_m;
    }
  }
  return reach;
}

}  // namespace anchormap
