#include "common/scan/occupancy_grid.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <unordered_map>

namespace anchormap {

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
    if (!p.allFinite() || p.cwiseAbs().maxCoeff() > kMaxGridCoordinateM) return;  // no cells
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
  for (const TracedCell& cell : tracer_.Trace(scan, T_map_body, options_)) {
    UpdateCell(cell.x, cell.y, cell.hit ? options_.log_odds_hit : options_.log_odds_miss);
  }
}

std::vector<GridTile> OccupancyGrid::Tiles(int64_t utime, int64_t update) const {
  std::vector<std::pair<std::pair<int32_t, int32_t>, const Tile*>> sorted;
  for (const auto& [key, tile] : tiles_) {
    const auto [tile_x, tile_y] = TileOfKey(key);
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
  cells.reserve(static_cast<size_t>(std::max(std::abs(x1 - x0), std::abs(y1 - y0)) + 1));
  ForEachBresenhamCell(x0, y0, x1, y1, [&](int64_t x, int64_t y) { cells.emplace_back(x, y); });
  return cells;
}

}  // namespace anchormap
