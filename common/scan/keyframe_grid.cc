#include "common/scan/keyframe_grid.h"

#include <algorithm>
#include <cmath>
#include <tuple>

#include "common/geometry/angle.h"

namespace anchormap {

KeyframeGrid::KeyframeGrid(const OccupancyGridOptions& options, double move_tolerance_cells)
    : options_(options), move_tolerance_m_(move_tolerance_cells * options.resolution_m) {}

KeyframeGrid::Counts* KeyframeGrid::TouchTile(int64_t tile_x, int64_t tile_y) {
  const uint64_t key = TileKey(tile_x, tile_y);
  Tile& tile = tiles_[key];
  const int64_t size = options_.tile_size_cells;
  if (tile.cells.empty()) tile.cells.resize(static_cast<size_t>(size * size));
  changed_.insert(key);
  return tile.cells.data();
}

namespace {
// Tables bigger than this (rays very long for the cell size) are not worth their filling:
// tiles are then found per cell.
constexpr int64_t kMaxWindowTiles = 4096;
}  // namespace

void KeyframeGrid::Trace(const LaserScan& scan, const Pose2& T_map_body, int sign) {
  const std::optional<ScanTracer::Window> window = tracer_.Start(scan, T_map_body, options_);
  if (!window) return;
  const int64_t size = options_.tile_size_cells;
  const int64_t side = window->side;
  const int64_t min_tile_x = FloorDiv(window->min_x, size);
  const int64_t min_tile_y = FloorDiv(window->min_y, size);
  const int64_t columns = FloorDiv(window->min_x + side - 1, size) - min_tile_x + 1;
  const int64_t rows = FloorDiv(window->min_y + side - 1, size) - min_tile_y + 1;
  if (columns * rows > kMaxWindowTiles) {
    Counts* tile = nullptr;
    int64_t tile_x = 0, tile_y = 0;
    tracer_.VisitCells([&](int64_t wx, int64_t wy, bool hit) {
      const int64_t x = window->min_x + wx, y = window->min_y + wy;
      const int64_t tx = FloorDiv(x, size), ty = FloorDiv(y, size);
      if (tile == nullptr || tx != tile_x || ty != tile_y) {
        tile = TouchTile(tx, ty);
        tile_x = tx;
        tile_y = ty;
      }
      Counts& counts = tile[(y - ty * size) * size + (x - tx * size)];
      (hit ? counts.hits : counts.misses) += sign;
    });
    return;
  }
  auto fill = [&](int64_t min, int64_t tile_stride, int64_t cell_stride, std::vector<int32_t>* tile,
                  std::vector<int32_t>* cell) {
    tile->resize(static_cast<size_t>(side));
    cell->resize(static_cast<size_t>(side));
    int64_t t = 0, c = min - FloorDiv(min, size) * size;
    for (int64_t w = 0; w < side; ++w) {
      (*tile)[w] = static_cast<int32_t>(t * tile_stride);
      (*cell)[w] = static_cast<int32_t>(c * cell_stride);
      if (++c == size) {
        c = 0;
        ++t;
      }
    }
  };
  fill(window->min_x, 1, 1, &column_tile_, &column_cell_);
  fill(window->min_y, columns, size, &row_tile_, &row_cell_);
  window_tiles_.assign(static_cast<size_t>(columns * rows), nullptr);
  const int32_t* const column_tile = column_tile_.data();
  const int32_t* const column_cell = column_cell_.data();
  const int32_t* const row_tile = row_tile_.data();
  const int32_t* const row_cell = row_cell_.data();
  Counts** const tiles = window_tiles_.data();
  tracer_.VisitCells([&](int64_t wx, int64_t wy, bool hit) {
    Counts*& tile = tiles[row_tile[wy] + column_tile[wx]];
    if (tile == nullptr) {
      tile = TouchTile(min_tile_x + column_tile[wx], min_tile_y + row_tile[wy] / columns);
    }
    Counts& counts = tile[row_cell[wy] + column_cell[wx]];
    counts.hits += hit ? sign : 0;
    counts.misses += hit ? 0 : sign;
  });
}

KeyframeGrid::Placement KeyframeGrid::Place(uint64_t key, const LaserScan& scan,
                                            const Pose2& T_map_body) {
  const auto it = placed_pose_.find(key);
  if (it == placed_pose_.end()) {
    Trace(scan, T_map_body, +1);
    placed_pose_.emplace(key, T_map_body);
    reach_m_[key] = ScanReach(scan, options_) + scan.T_body_sensor.translation().norm();
    return Placement::kInserted;
  }
  const Pose2& old = it->second;
  const double moved = *Displacement(key, T_map_body);
  if (!(moved > move_tolerance_m_)) return Placement::kUnchanged;
  Trace(scan, old, -1);
  Trace(scan, T_map_body, +1);
  it->second = T_map_body;
  return Placement::kMoved;
}

std::optional<double> KeyframeGrid::Displacement(uint64_t key, const Pose2& T_map_body) const {
  const auto it = placed_pose_.find(key);
  if (it == placed_pose_.end()) return std::nullopt;
  const Pose2& old = it->second;
  return (T_map_body.translation() - old.translation()).norm() +
         std::abs(AngleDifference(T_map_body.theta(), old.theta())) * reach_m_.at(key);
}

bool KeyframeGrid::Remove(uint64_t key, const LaserScan& scan) {
  const auto it = placed_pose_.find(key);
  if (it == placed_pose_.end()) return false;
  Trace(scan, it->second, -1);
  placed_pose_.erase(it);
  reach_m_.erase(key);
  return true;
}

std::optional<double> KeyframeGrid::LogOdds(const Counts& counts) const {
  if (counts.hits == 0 && counts.misses == 0) return std::nullopt;
  return std::clamp(counts.hits * options_.log_odds_hit + counts.misses * options_.log_odds_miss,
                    options_.log_odds_min, options_.log_odds_max);
}

std::optional<double> KeyframeGrid::LogOdds(int64_t cell_x, int64_t cell_y) const {
  const int64_t size = options_.tile_size_cells;
  const int64_t tile_x = FloorDiv(cell_x, size), tile_y = FloorDiv(cell_y, size);
  const auto it = tiles_.find(TileKey(tile_x, tile_y));
  if (it == tiles_.end()) return std::nullopt;
  return LogOdds(
      it->second
          .cells[static_cast<size_t>((cell_y - tile_y * size) * size + (cell_x - tile_x * size))]);
}

int8_t KeyframeGrid::Occupancy(int64_t cell_x, int64_t cell_y) const {
  const auto log_odds = LogOdds(cell_x, cell_y);
  return log_odds ? OccupancyFromLogOdds(*log_odds) : int8_t{-1};
}

GridTile KeyframeGrid::Export(uint64_t key, const Tile& tile, int64_t utime, int64_t update) const {
  GridTile t;
  t.utime = utime;
  t.update = update;
  t.resolution_m = options_.resolution_m;
  std::tie(t.tile_x, t.tile_y) = TileOfKey(key);
  t.width = t.height = options_.tile_size_cells;
  t.cells.reserve(tile.cells.size());
  for (const Counts& counts : tile.cells) {
    const auto log_odds = LogOdds(counts);
    t.cells.push_back(log_odds ? OccupancyFromLogOdds(*log_odds) : int8_t{-1});
  }
  return t;
}

namespace {
// (tile_y, tile_x) order, as OccupancyGrid::Tiles.
bool RowMajor(uint64_t a, uint64_t b) {
  const auto [ax, ay] = TileOfKey(a);
  const auto [bx, by] = TileOfKey(b);
  return std::make_pair(ay, ax) < std::make_pair(by, bx);
}
}  // namespace

std::vector<GridTile> KeyframeGrid::Tiles(int64_t utime, int64_t update) const {
  std::vector<uint64_t> keys;
  keys.reserve(tiles_.size());
  for (const auto& [key, tile] : tiles_) keys.push_back(key);
  std::sort(keys.begin(), keys.end(), RowMajor);
  std::vector<GridTile> out;
  out.reserve(keys.size());
  for (uint64_t key : keys) out.push_back(Export(key, tiles_.at(key), utime, update));
  return out;
}

std::vector<GridTile> KeyframeGrid::TakeChangedTiles(int64_t utime, int64_t update) {
  std::vector<uint64_t> keys(changed_.begin(), changed_.end());
  changed_.clear();
  std::sort(keys.begin(), keys.end(), RowMajor);
  std::vector<GridTile> out;
  out.reserve(keys.size());
  for (uint64_t key : keys) out.push_back(Export(key, tiles_.at(key), utime, update));
  return out;
}

}  // namespace anchormap
