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
  for (size_t i = 0; i < scan.ranges.size(); ++i) {
    const double angle = scan.Angle(i);
    const Eigen::Vector2d direction(std::cos(angle), std::sin(angle));
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
