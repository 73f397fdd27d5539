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
  window_ = {x0 - radius, y0 - radius, 2 * radius + 1};
  sensor_wx_ = sensor_wy_ = radius;
  const int64_t side = window_.side;
  // The window costs 2 bytes a cell: up to 2049^2 cells (8 MB).
  use_window_ = side <= kMaxWindowSide;
  if (use_window_) {
    if (stamps_.size() != static_cast<size_t>(side * side) || visited_stamp_ >= 0xfffe) {
      stamps_.assign(static_cast<size_t>(side * side), 0);  // new size, or every stamp used
      visited_stamp_ = 0;
    }
    hit_stamp_ = static_cast<uint16_t>(visited_stamp_ + 1);
    visited_stamp_ = static_cast<uint16_t>(visited_stamp_ + 2);
  } else {
    far_cells_.clear();
  }
  // The beams' end cells; the ends of returns within the ray length are marked as hits
  // first, so that each cell is reported once, with its final flag.
  auto end = [&](const Eigen::Vector2d& p_map, bool hit) {
    const auto [x1, y1] = Cell(p_map, options.resolution_m);
    const BeamEnd beam_end{x1 - window_.min_x, y1 - window_.min_y};
    ends_.push_back(beam_end);
    if (!hit) return;
    if (use_window_) {
      stamps_[static_cast<size_t>(beam_end.wy * side + beam_end.wx)] = hit_stamp_;
    } else {
      far_cells_[TileKey(beam_end.wx, beam_end.wy)] = 1;
    }
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

void ScanTracer::MarkCells() {
  const int64_t side = window_.side;
  row_min_.assign(static_cast<size_t>(side), static_cast<int32_t>(side));
  row_max_.assign(static_cast<size_t>(side), -1);
  uint16_t* const stamps = stamps_.data();
  int32_t* const row_min = row_min_.data();
  int32_t* const row_max = row_max_.data();
  const uint16_t hit_stamp = hit_stamp_, visited_stamp = visited_stamp_;
  auto extend = [&](int64_t x, int64_t y) {
    row_min[y] = std::min(row_min[y], static_cast<int32_t>(x));
    row_max[y] = std::max(row_max[y], static_cast<int32_t>(x));
  };
  extend(sensor_wx_, sensor_wy_);
  // Walk's steps, with a row's extent widened only where a beam enters or leaves the row
  // (x moves monotonically along a beam): at a step to the next row, the old row by the new
  // x (one cell past its last, harmless) and the new row by it; the end cell's row by the
  // end (a beam that ends in the row it started in).
  for (const BeamEnd& end : ends_) {
    Walk(
        end,
        [&](int64_t, int64_t, int64_t index) {
          uint16_t& stamp = stamps[index];
          stamp = stamp == hit_stamp ? hit_stamp : visited_stamp;
        },
        [&](int64_t x, int64_t from_y, int64_t to_y) {
          extend(x, from_y);
          extend(x, to_y);
        });
    extend(end.wx, end.wy);
  }
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
