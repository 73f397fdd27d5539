#include "common/scan/scan_tracer.h"

#include <algorithm>
#include <cmath>

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

std::optional<ScanTracer::Window> ScanTracer::Start(const LaserScan& scan, const Pose2& T_map_body,
                                                    const OccupancyGridOptions& options) {
  ends_.clear();
  const Pose2 T_map_sensor = Compose(T_map_body, scan.T_body_sensor);
  const Eigen::Vector2d origin = T_map_sensor.translation();
  // A pose that is not finite, or absurdly far away, has no cells (the fuzzer fed one
  // through the server).
  if (!T_map_sensor.IsFinite() || origin.cwiseAbs().maxCoeff() > kMaxGridCoordinateM) {
    return std::nullopt;
  }
  const auto [x0, y0] = Cell(origin, options.resolution_m);
  // Every traced cell lies within `radius` of the sensor's cell (rays end within
  // max_ray_length_m).
  const int64_t radius =
      static_cast<int64_t>(std::ceil(options.max_ray_length_m / options.resolution_m)) + 2;
  // The window's columns start at a multiple of kMarkGroup in map coordinates and its side
  // is a multiple of it, so that MarkCells' rows come in whole aligned groups.
  const int64_t min_x = FloorDiv(x0 - radius, kMarkGroup) * kMarkGroup;
  // A side of a multiple of 64 (1024 for the server's 25 m at 5 cm) would put a beam's steps
  // from row to row in few cache sets: one more group then.
  int64_t side = (2 * radius + 2 * kMarkGroup - 1) / kMarkGroup * kMarkGroup;
  if (side % 64 == 0) side += kMarkGroup;
  window_ = {min_x, y0 - radius, side};
  sensor_wx_ = x0 - min_x;
  sensor_wy_ = radius;
  // The window costs 2 bytes a cell in VisitCells' stamps: up to 2049^2 cells (8 MB).
  use_window_ = 2 * radius + 1 <= kMaxWindowSide;
  // The beams' end cells, and whether each is the end of a return within the ray length.
  auto end = [&](const Eigen::Vector2d& p_map, bool hit) {
    const auto [x1, y1] = Cell(p_map, options.resolution_m);
    ends_.push_back({x1 - window_.min_x, y1 - window_.min_y, hit});
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
  return window_;
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
    for (const BeamEnd& end : ends_) {
      if (end.hit) stamps_[static_cast<size_t>(end.wy * side + end.wx)] = hit_stamp_;
    }
  } else {
    far_cells_.clear();
    for (const BeamEnd& end : ends_) {
      if (end.hit) far_cells_[TileKey(end.wx, end.wy)] = 1;
    }
  }
}

void ScanTracer::ClearMarks() {
  ForEachMarkedRow([](int64_t, int64_t, int64_t, const uint8_t*) {});
}

void ScanTracer::MarkCells() {
  const int64_t side = window_.side;
  if (marks_.size() != static_cast<size_t>(side * side)) {
    marks_.assign(static_cast<size_t>(side * side), 0);
    for (auto& reach : reach_) reach.assign(static_cast<size_t>(side), 0);
    beam_reach_.assign(static_cast<size_t>(side), 0);
    marks_dirty_ = false;
  } else if (marks_dirty_) {
    ClearMarks();
  }
  uint8_t* const marks = marks_.data();
  int16_t* const beam_reach = beam_reach_.data();
  const int64_t x0 = sensor_wx_, y0 = sensor_wy_;
  first_row_ = last_row_ = y0;
  marked_x0_ = x0;
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
  // pass over its rows.
  for (const BeamEnd& end : ends_) {
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
    int16_t* const reach = reach_[sx > 0 ? 1 : 0].data();
    const int64_t from = std::min(y0, end.wy), to = std::max(y0, end.wy);
    for (int64_t r = from; r <= to; ++r) reach[r] = std::max(reach[r], beam_reach[r]);
    first_row_ = std::min(first_row_, from);
    last_row_ = std::max(last_row_, to);
  }
  for (const BeamEnd& end : ends_) {
    if (end.hit) marks[end.wy * side + end.wx] = kHitMark;
  }
  marks_dirty_ = true;
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
