#include "common/scan/occupancy_grid.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <unordered_map>

namespace anchormap {
namespace {

int64_t FloorDiv(int64_t a, int64_t b) {
  int64_t q = a / b;
  if ((a % b != 0) && ((a < 0) != (b < 0))) --q;
  return q;
}

int8_t OccupancyFromLogOdds(double log_odds) {
  const double p = 1.0 - 1.0 / (1.0 + std::exp(log_odds));
  return static_cast<int8_t>(std::lround(100.0 * p));
}

}  // namespace

Status OccupancyGridOptions::Validate() const {
  if (!(resolution_m > 0)) return Status::Error("grid resolution_m must be > 0");
  if (tile_size_cells < 8 || tile_size_cells > 4096)
    return Status::Error("grid tile_size_cells must be 8..4096");
  if (!(log_odds_hit > 0)) return Status::Error("grid log_odds_hit must be > 0");
  if (!(log_odds_miss < 0)) return Status::Error("grid log_odds_miss must be < 0");
  if (!(log_odds_min < 0) || !(log_odds_max > 0))
    return Status::Error("grid log_odds_min < 0 < log_odds_max");
  if (!(max_ray_length_m > 0)) return Status::Error("grid max_ray_length_m must be > 0");
  if (max_ray_length_m / resolution_m > 1e6)
    return Status::Error("grid max_ray_length_m / resolution_m too large");
  return Status::Ok();
}

OccupancyGrid::OccupancyGrid(const OccupancyGridOptions& options) : options_(options) {}

namespace {
// Farther than this from the map's origin, a point has no cell (1e7 m at 5 cm is 2e8 cells).
constexpr double kMaxCoordinateM = 1e7;
}  // namespace

uint64_t OccupancyGrid::TileKey(int64_t tile_x, int64_t tile_y) {
  return (static_cast<uint64_t>(static_cast<uint32_t>(tile_x)) << 32) |
         static_cast<uint64_t>(static_cast<uint32_t>(tile_y));
}

std::pair<int64_t, int64_t> OccupancyGrid::CellOf(const Eigen::Vector2d& p_map) const {
  return {static_cast<int64_t>(std::floor(p_map.x() / options_.resolution_m)),
          static_cast<int64_t>(std::floor(p_map.y() / options_.resolution_m))};
}

void OccupancyGrid::UpdateCell(int64_t cell_x, int64_t cell_y, double delta) {
  const int64_t size = options_.tile_size_cells;
  const int64_t tile_x = FloorDiv(cell_x, size), tile_y = FloorDiv(cell_y, size);
  Tile& tile = tiles_[TileKey(tile_x, tile_y)];
  if (tile.log_odds.empty()) {
    tile.log_odds.assign(static_cast<size_t>(size * size), std::numeric_limits<float>::quiet_NaN());
  }
  const size_t index =
      static_cast<size_t>((cell_y - tile_y * size) * size + (cell_x - tile_x * size));
  float& value = tile.log_odds[index];
  const double old = std::isnan(value) ? 0.0 : value;
  value = static_cast<float>(std::clamp(old + delta, options_.log_odds_min, options_.log_odds_max));
}

std::optional<double> OccupancyGrid::LogOdds(int64_t cell_x, int64_t cell_y) const {
  const int64_t size = options_.tile_size_cells;
  const int64_t tile_x = FloorDiv(cell_x, size), tile_y = FloorDiv(cell_y, size);
  const auto it = tiles_.find(TileKey(tile_x, tile_y));
  if (it == tiles_.end()) return std::nullopt;
  const float value = it->second.log_odds[static_cast<size_t>((cell_y - tile_y * size) * size +
                                                              (cell_x - tile_x * size))];
  if (std::isnan(value)) return std::nullopt;
  return value;
}

int8_t OccupancyGrid::Occupancy(int64_t cell_x, int64_t cell_y) const {
  const auto log_odds = LogOdds(cell_x, cell_y);
  return log_odds ? OccupancyFromLogOdds(*log_odds) : int8_t{-1};
}

void OccupancyGrid::InsertRay(const Eigen::Vector2d& from_map, const Eigen::Vector2d& to_map,
                              bool hit) {
  for (const Eigen::Vector2d& p : {from_map, to_map}) {
    if (!p.allFinite() || p.cwiseAbs().maxCoeff() > kMaxCoordinateM) return;  // no cells
  }
  const auto [x0, y0] = CellOf(from_map);
  const auto [x1, y1] = CellOf(to_map);
  const auto cells = BresenhamLine(x0, y0, x1, y1);
  for (size_t i = 0; i + 1 < cells.size(); ++i) {
    UpdateCell(cells[i].first, cells[i].second, options_.log_odds_miss);
  }
  UpdateCell(x1, y1, hit ? options_.log_odds_hit : options_.log_odds_miss);
}

void OccupancyGrid::InsertScan(const LaserScan& scan, const Pose2& T_map_body) {
  // Each cell is updated at most once per scan (a hit wins over a miss), so that the
  // beam density near the sensor does not count as repeated evidence. Cells are
  // de-duplicated in a window around the sensor stamped with the scan number (sorting the
  // traced cells cost 40 % of a 10-robot server run).
  const Pose2 T_map_sensor = Compose(T_map_body, scan.T_body_sensor);
  const Eigen::Vector2d origin = T_map_sensor.translation();
  // A pose that is not finite, or absurdly far away, has no cells (its cell numbers would
  // overflow): such a scan is skipped (the fuzzer fed one through the server).
  if (!T_map_sensor.IsFinite() || origin.cwiseAbs().maxCoeff() > kMaxCoordinateM) return;
  const auto [x0, y0] = CellOf(origin);
  const int64_t radius =
      static_cast<int64_t>(std::ceil(options_.max_ray_length_m / options_.resolution_m)) + 2;
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
  // Each cell traced by this scan, once, with its hit flag (in the window, or in a hash
  // map whose nodes do not move).
  struct Visited {
    int64_t x, y;
    const uint8_t* hit;
  };
  std::vector<Visited> cells;
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
      cells.push_back({x, y, flag});
    } else if (hit) {
      *flag = 1;
    }
  };
  auto trace = [&, x0 = x0, y0 = y0](const Eigen::Vector2d& end, bool hit) {
    const auto [x1, y1] = CellOf(end);
    const auto line = BresenhamLine(x0, y0, x1, y1);
    for (size_t i = 0; i + 1 < line.size(); ++i) visit(line[i].first, line[i].second, false);
    visit(x1, y1, hit);
  };
  for (size_t i = 0; i < scan.ranges.size(); ++i) {
    const double angle = scan.Angle(i);
    const Eigen::Vector2d direction(std::cos(angle), std::sin(angle));
    if (scan.IsReturn(i)) {
      const double range = scan.ranges[i];
      const double length = std::min<double>(range, options_.max_ray_length_m);
      trace(T_map_sensor.TransformPoint(length * direction), range <= options_.max_ray_length_m);
    } else if (options_.no_return_as_free) {
      trace(T_map_sensor.TransformPoint(options_.max_ray_length_m * direction), false);
    }
  }
  for (const Visited& cell : cells) {
    UpdateCell(cell.x, cell.y, *cell.hit ? options_.log_odds_hit : options_.log_odds_miss);
  }
}

std::vector<GridTile> OccupancyGrid::Tiles(int64_t utime, int64_t update) const {
  std::vector<std::pair<std::pair<int32_t, int32_t>, const Tile*>> sorted;
  for (const auto& [key, tile] : tiles_) {
    const auto tile_x = static_cast<int32_t>(static_cast<uint32_t>(key >> 32));
    const auto tile_y = static_cast<int32_t>(static_cast<uint32_t>(key & 0xffffffffu));
    sorted.push_back({{tile_y, tile_x}, &tile});
  }
  std::sort(sorted.begin(), sorted.end(),
            [](const auto& a, const auto& b) { return a.first < b.first; });
  std::vector<GridTile> out;
  out.reserve(sorted.size());
  for (const auto& [index, tile] : sorted) {
    GridTile t;
    t.utime = utime;
    t.update = update;
    t.resolution_m = options_.resolution_m;
    t.tile_x = index.second;
    t.tile_y = index.first;
    t.width = t.height = options_.tile_size_cells;
    t.cells.reserve(tile->log_odds.size());
    for (float value : tile->log_odds) {
      t.cells.push_back(std::isnan(value) ? int8_t{-1} : OccupancyFromLogOdds(value));
    }
    out.push_back(std::move(t));
  }
  return out;
}

std::vector<std::pair<int64_t, int64_t>> BresenhamLine(int64_t x0, int64_t y0, int64_t x1,
                                                       int64_t y1) {
  std::vector<std::pair<int64_t, int64_t>> cells;
  const int64_t dx = std::abs(x1 - x0), dy = -std::abs(y1 - y0);
  const int64_t sx = x0 < x1 ? 1 : -1, sy = y0 < y1 ? 1 : -1;
  cells.reserve(static_cast<size_t>(std::max(dx, -dy) + 1));
  int64_t error = dx + dy;
  while (true) {
    cells.emplace_back(x0, y0);
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
  return cells;
}

}  // namespace anchormap
