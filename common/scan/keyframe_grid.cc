#include "common/scan/keyframe_grid.h"

#include <algorithm>
#include <cmath>
#include <tuple>
#include <type_traits>

#include "common/geometry/angle.h"

namespace anchormap {

KeyframeGrid::KeyframeGrid(const OccupancyGridOptions& options, double move_tolerance_cells)
    : options_(options),
      move_tolerance_m_(move_tolerance_cells * options.resolution_m),
      cells_per_tile_(static_cast<int64_t>(options.tile_size_cells) * options.tile_size_cells),
      small_counts_(static_cast<size_t>(kTableHits * kTableMisses)) {
  for (int32_t hits = 0; hits < kTableHits; ++hits) {
    for (int32_t misses = 0; misses < kTableMisses; ++misses) {
      small_counts_[static_cast<size_t>(hits * kTableMisses + misses)] =
          CellOccupancy(hits, misses);
    }
  }
}

namespace {
// A tile's counts of width Count.
template <typename Count, typename Tile>
auto& CountsOf(Tile& tile) {
  if constexpr (std::is_same_v<Count, int16_t>) {
    return tile.narrow;
  } else {
    return tile.wide;
  }
}
}  // namespace

template <typename Count>
Count* KeyframeGrid::TouchTile(int64_t tile_x, int64_t tile_y) {
  const uint64_t key = TileKey(tile_x, tile_y);
  Tile& tile = tiles_[key];
  auto& counts = CountsOf<Count>(tile);
  if (counts.empty()) counts.resize(static_cast<size_t>(2 * cells_per_tile_));
  changed_.insert(key);
  return counts.data();
}

void KeyframeGrid::Reserve(size_t placed) {
  if (wide_ || placed <= kMaxNarrowPlaced) return;
  for (auto& [key, tile] : tiles_) {
    tile.wide.assign(tile.narrow.begin(), tile.narrow.end());
    tile.narrow = std::vector<int16_t>();
  }
  wide_ = true;
}

namespace {
// Tables bigger than this (rays very long for the cell size) are not worth their filling:
// tiles are then found per cell.
constexpr int64_t kMaxWindowTiles = 4096;
}  // namespace

template <typename Count>
void KeyframeGrid::TraceCellByCell(const ScanTracer::Window& window, int sign) {
  const int64_t size = options_.tile_size_cells;
  Count* tile = nullptr;
  int64_t tile_x = 0, tile_y = 0;
  tracer_.VisitCells([&](int64_t wx, int64_t wy, bool hit) {
    const int64_t x = window.min_x + wx, y = window.min_y + wy;
    const int64_t tx = FloorDiv(x, size), ty = FloorDiv(y, size);
    if (tile == nullptr || tx != tile_x || ty != tile_y) {
      tile = TouchTile<Count>(tx, ty);
      tile_x = tx;
      tile_y = ty;
    }
    tile[(hit ? 0 : cells_per_tile_) + (y - ty * size) * size + (x - tx * size)] +=
        static_cast<Count>(sign);
  });
}

void KeyframeGrid::Trace(const LaserScan& scan, const Pose2& T_map_body, int sign) {
  const std::optional<ScanTracer::Window> window = tracer_.Start(scan, T_map_body, options_);
  if (!window) return;
  if (!tracer_.MarksInWindow() || WindowTiles(*window).count() > kMaxWindowTiles) {
    wide_ ? TraceCellByCell<int32_t>(*window, sign) : TraceCellByCell<int16_t>(*window, sign);
  } else {
    wide_ ? TraceRows<int32_t>(*window, sign) : TraceRows<int16_t>(*window, sign);
  }
}

void KeyframeGrid::Move(const LaserScan& scan, const Pose2& T_map_from, const Pose2& T_map_to) {
  const std::optional<ScanTracer::Window> window =
      tracer_.StartMove(scan, T_map_from, T_map_to, options_);
  if (!window || !tracer_.MarksInWindow() || WindowTiles(*window).count() > kMaxWindowTiles) {
    Trace(scan, T_map_from, -1);
    Trace(scan, T_map_to, +1);
    return;
  }
  wide_ ? TraceMoveRows<int32_t>(*window) : TraceMoveRows<int16_t>(*window);
}

KeyframeGrid::TileSpan KeyframeGrid::WindowTiles(const ScanTracer::Window& window) const {
  const int64_t size = options_.tile_size_cells;
  TileSpan span;
  span.min_x = FloorDiv(window.min_x, size);
  span.min_y = FloorDiv(window.min_y, size);
  span.columns = FloorDiv(window.min_x + window.side - 1, size) - span.min_x + 1;
  span.rows = FloorDiv(window.min_y + window.side - 1, size) - span.min_y + 1;
  return span;
}

template <typename Count>
void KeyframeGrid::AddHit(const ScanTracer::Window& window, const TileSpan& span, int64_t wx,
                          int64_t wy, Count add) {
  const int64_t size = options_.tile_size_cells;
  const int64_t x = window.min_x + wx, y = window.min_y + wy;
  const int64_t tx = FloorDiv(x, size), ty = FloorDiv(y, size);
  void*& tile =
      window_tiles_[static_cast<size_t>((ty - span.min_y) * span.columns + (tx - span.min_x))];
  if (tile == nullptr) tile = TouchTile<Count>(tx, ty);
  static_cast<Count*>(tile)[(y - ty * size) * size + (x - tx * size)] += add;
}

template <typename Count, typename Traced, typename Add>
void KeyframeGrid::AddRowMisses(const ScanTracer::Window& window, const TileSpan& span, int64_t wy,
                                int64_t first, int64_t last, Traced traced, Add add) {
  // One run of consecutive cells per tile the row's extent crosses.
  const int64_t size = options_.tile_size_cells;
  const int64_t y = window.min_y + wy;
  const int64_t ty = FloorDiv(y, size);
  const int64_t row_offset = (y - ty * size) * size;
  void** const tile_row = &window_tiles_[static_cast<size_t>((ty - span.min_y) * span.columns)];
  const int64_t last_x = window.min_x + last;
  for (int64_t x = window.min_x + first; x <= last_x;) {
    const int64_t tx = FloorDiv(x, size);
    const int64_t n = std::min(last_x + 1, (tx + 1) * size) - x;
    const int64_t wx = x - window.min_x;
    void*& tile = tile_row[tx - span.min_x];
    if (tile == nullptr) {
      // A run between two traced stretches of the row may hold none: a tile is touched
      // only for a traced cell, as cell by cell.
      uint8_t any = 0;
      for (int64_t i = 0; i < n; ++i) any |= traced(wx + i);
      if (any != 0) tile = TouchTile<Count>(tx, ty);
    }
    if (tile != nullptr) {
      Count* const misses =
          static_cast<Count*>(tile) + cells_per_tile_ + row_offset + (x - tx * size);
      // In whole groups when it can (the tile's side a multiple of the group's): no
      // remainder loop.
      const int64_t groups = n % ScanTracer::kMarkGroup == 0 ? n : 0;
      for (int64_t g = 0; g < groups; g += ScanTracer::kMarkGroup) {
        for (int64_t i = g; i < g + ScanTracer::kMarkGroup; ++i) misses[i] += add(wx + i);
      }
      for (int64_t i = groups; i < n; ++i) misses[i] += add(wx + i);
    }
    x += n;
  }
}

template <typename Count>
void KeyframeGrid::TraceRows(const ScanTracer::Window& window, int sign) {
  const TileSpan span = WindowTiles(window);
  // The beams leave marks in the tracer's window; the counts are then added row by row.
  tracer_.MarkCells();
  window_tiles_.assign(static_cast<size_t>(span.count()), nullptr);
  const Count add = static_cast<Count>(sign);
  // Hits are rare (at most one per beam): counted one by one, so that the rows below read
  // and write only the misses' counts.
  tracer_.ForEachHit([&](int64_t wx, int64_t wy) { AddHit(window, span, wx, wy, add); });
  tracer_.ForEachMarkedRow([&](int64_t wy, int64_t first, int64_t last, const uint8_t* marks) {
    AddRowMisses<Count>(
        window, span, wy, first, last, [marks](int64_t wx) { return marks[wx]; },
        [marks, add](int64_t wx) { return marks[wx] == ScanTracer::kMissMark ? add : Count{0}; });
  });
}

template <typename Count>
void KeyframeGrid::TraceMoveRows(const ScanTracer::Window& window) {
  const TileSpan span = WindowTiles(window);
  // Both traces leave marks in one window; each row's counts are then read and written once
  // for both, by the difference of the two traces' misses.
  tracer_.MarkMove();
  window_tiles_.assign(static_cast<size_t>(span.count()), nullptr);
  tracer_.ForEachMoveHit([&](int64_t wx, int64_t wy, bool in) {
    AddHit(window, span, wx, wy, static_cast<Count>(in ? 1 : -1));
  });
  tracer_.ForEachMoveRow(
      [&](int64_t wy, int64_t first, int64_t last, const uint8_t* out, const uint8_t* in) {
        AddRowMisses<Count>(
            window, span, wy, first, last,
            [out, in](int64_t wx) { return static_cast<uint8_t>(out[wx] | in[wx]); },
            [out, in](int64_t wx) {
              return static_cast<Count>((in[wx] == ScanTracer::kMissMark) -
                                        (out[wx] == ScanTracer::kMissMark));
            });
      });
}

KeyframeGrid::Placement KeyframeGrid::Place(uint64_t key, const LaserScan& scan,
                                            const Pose2& T_map_body) {
  const auto it = placed_pose_.find(key);
  if (it == placed_pose_.end()) {
    Reserve(placed_pose_.size() + 1);
    Trace(scan, T_map_body, +1);
    placed_pose_.emplace(key, T_map_body);
    reach_m_[key] = ReachFromBody(scan);
    return Placement::kInserted;
  }
  const Pose2& old = it->second;
  const double moved = *Displacement(key, T_map_body);
  if (!(moved > move_tolerance_m_)) return Placement::kUnchanged;
  Move(scan, old, T_map_body);
  it->second = T_map_body;
  return Placement::kMoved;
}

double KeyframeGrid::ReachFromBody(const LaserScan& scan) const {
  return ScanReach(scan, options_) + scan.T_body_sensor.translation().norm();
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

void KeyframeGrid::Rebuild(const std::vector<Keyframe>& keyframes) {
  Reserve(keyframes.size());
  for (auto& [key, tile] : tiles_) {
    std::fill(tile.narrow.begin(), tile.narrow.end(), int16_t{0});
    std::fill(tile.wide.begin(), tile.wide.end(), 0);
    changed_.insert(key);
  }
  placed_pose_.clear();
  reach_m_.clear();
  for (const Keyframe& keyframe : keyframes) {
    Trace(*keyframe.scan, keyframe.T_map_body, +1);
    placed_pose_[keyframe.key] = keyframe.T_map_body;
    reach_m_[keyframe.key] = ReachFromBody(*keyframe.scan);
  }
}

std::optional<double> KeyframeGrid::LogOdds(int32_t hits, int32_t misses) const {
  if (hits == 0 && misses == 0) return std::nullopt;
  return std::clamp(hits * options_.log_odds_hit + misses * options_.log_odds_miss,
                    options_.log_odds_min, options_.log_odds_max);
}

std::optional<double> KeyframeGrid::LogOdds(int64_t cell_x, int64_t cell_y) const {
  const int64_t size = options_.tile_size_cells;
  const int64_t tile_x = FloorDiv(cell_x, size), tile_y = FloorDiv(cell_y, size);
  const auto it = tiles_.find(TileKey(tile_x, tile_y));
  if (it == tiles_.end()) return std::nullopt;
  const size_t cell =
      static_cast<size_t>((cell_y - tile_y * size) * size + (cell_x - tile_x * size));
  const Tile& tile = it->second;
  return wide_ ? LogOdds(tile.wide[cell], tile.wide[cell + cells_per_tile_])
               : LogOdds(tile.narrow[cell], tile.narrow[cell + cells_per_tile_]);
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
  t.cells.resize(static_cast<size_t>(cells_per_tile_));
  if (wide_) {
    ExportCells(tile.wide.data(), &t);
  } else {
    ExportCells(tile.narrow.data(), &t);
  }
  return t;
}

int8_t KeyframeGrid::CellOccupancy(int32_t hits, int32_t misses) const {
  const auto log_odds = LogOdds(hits, misses);
  return log_odds ? OccupancyFromLogOdds(*log_odds) : int8_t{-1};
}

template <typename Count>
void KeyframeGrid::ExportCells(const Count* hits, GridTile* tile) const {
  // Counts within the table are looked up (a publication exports every cell of each changed
  // tile; free space's counts change from cell to cell, so a run's value rarely served), the
  // others computed.
  const Count* const misses = hits + cells_per_tile_;
  const int8_t* const table = small_counts_.data();
  for (int64_t i = 0; i < cells_per_tile_; ++i) {
    const int32_t h = hits[i], m = misses[i];
    tile->cells[static_cast<size_t>(i)] =
        static_cast<uint32_t>(h) < static_cast<uint32_t>(kTableHits) &&
                static_cast<uint32_t>(m) < static_cast<uint32_t>(kTableMisses)
            ? table[h * kTableMisses + m]
            : CellOccupancy(h, m);
  }
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
