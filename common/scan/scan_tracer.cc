#include "common/scan/scan_tracer.h"

#include <algorithm>
#include <cmath>

#include "common/scan/occupancy_grid.h"

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
  const Pose2 T_map_sensor = Compose(T_map_body, scan.T_body_sensor);
  const Eigen::Vector2d origin = T_map_sensor.translation();
  // A pose that is not finite, or absurdly far away, has no cells (the fuzzer fed one
  // through the server).
  if (!T_map_sensor.IsFinite() || origin.cwiseAbs().maxCoeff() > kMaxGridCoordinateM) {
    return cells_;
  }
  const auto [x0, y0] = Cell(origin, options.resolution_m);
  const int64_t radius =
      static_cast<int64_t>(std::ceil(options.max_ray_length_m / options.resolution_m)) + 2;
  const int64_t side = 2 * radius + 1;
  // The window costs 5 bytes a cell: up to 2049^2 cells (20 MB); longer rays relative to
  // the resolution fall back to a hash map.
  const bool use_window = side <= 2049;
  if (use_window && window_stamp_.size() != static_cast<size_t>(side * side)) {
    window_stamp_.assign(side * side, 0);
    window_hit_.assign(side * side, 0);
    scan_stamp_ = 0;
  }
  if (use_window && ++scan_stamp_ == 0) {  // wrapped: forget every stamp
    std::fill(window_stamp_.begin(), window_stamp_.end(), 0);
    scan_stamp_ = 1;
  }
  // Each traced cell once, with a pointer to its hit flag (in the window, or in a hash map
  // whose nodes do not move).
  std::vector<Visited>& visited = visited_;
  visited.clear();
  std::unordered_map<uint64_t, uint8_t> far_cells;  // only without the window
  // Every traced cell lies within `radius` of the sensor's cell (rays end within
  // max_ray_length_m), so window indices are in range.
  auto visit = [&, x0 = x0, y0 = y0](int64_t x, int64_t y, bool hit) {
    uint8_t* flag;
    bool first;
    if (use_window) {
      const size_t index = static_cast<size_t>((y - y0 + radius) * side + (x - x0 + radius));
      first = window_stamp_[index] != scan_stamp_;
      window_stamp_[index] = scan_stamp_;
      flag = &window_hit_[index];
    } else {
      auto [it, inserted] = far_cells.try_emplace(TileKey(x, y), 0);
      first = inserted;
      flag = &it->second;
    }
    if (first) {
      *flag = hit;
      visited.push_back({x, y, flag});
    } else if (hit) {
      *flag = 1;
    }
  };
  auto trace = [&, x0 = x0, y0 = y0](const Eigen::Vector2d& end, bool hit) {
    const auto [x1, y1] = Cell(end, options.resolution_m);
    // The line's cells are misses but its last, (x1, y1).
    ForEachBresenhamCell(x0, y0, x1, y1, [&, x1 = x1, y1 = y1](int64_t x, int64_t y) {
      visit(x, y, x == x1 && y == y1 && hit);
    });
  };
  for (size_t i = 0; i < scan.ranges.size(); ++i) {
    const double angle = scan.Angle(i);
    const Eigen::Vector2d direction(std::cos(angle), std::sin(angle));
    if (scan.IsReturn(i)) {
      const double range = scan.ranges[i];
      const double length = std::min<double>(range, options.max_ray_length_m);
      trace(T_map_sensor.TransformPoint(length * direction), range <= options.max_ray_length_m);
    } else if (options.no_return_as_free) {
      trace(T_map_sensor.TransformPoint(options.max_ray_length_m * direction), false);
    }
  }
  cells_.reserve(visited.size());
  for (const Visited& cell : visited) cells_.push_back({cell.x, cell.y, *cell.hit != 0});
  return cells_;
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
