#pragma once
// The server's occupancy grid: made of keyframes' scans whose poses keep moving as the
// solver refines them, and kept up to date by moving only the scans whose keyframe moved by
// about a cell since it was traced, instead of being rebuilt from every keyframe.
//
// Each cell counts its hits and misses; its log-odds are the clamped sum
// clamp(hits * log_odds_hit + misses * log_odds_miss) (the inverse sensor model of
// OccupancyGrid, clamped once at the end instead of after each scan), so that a scan can be
// taken out exactly (it is traced again at the pose it went in with) and the grid does not
// depend on the order of the scans: after any sequence of moves it equals a grid built from
// scratch at the poses the scans were last placed at.
// The tiles changed since they were last taken are tracked, so that only they need to be
// published.

#include <cstdint>
#include <optional>
#include <unordered_map>
#include <unordered_set>
#include <utility>
#include <vector>

#include "common/geometry/pose2.h"
#include "common/scan/grid_cells.h"
#include "common/scan/scan_tracer.h"
#include "common/types/laser_scan.h"
#include "common/types/map_outputs.h"

namespace anchormap {

class KeyframeGrid {
 public:
  // A scan is traced again when its far beam ends moved more than this many cells (its
  // translation plus its rotation times the scan's reach).
  explicit KeyframeGrid(const OccupancyGridOptions& options = {},
                        double move_tolerance_cells = 1.0);
  const OccupancyGridOptions& options() const { return options_; }

  enum class Placement { kUnchanged, kInserted, kMoved };
  // Keyframe `key`'s scan at T_map_body: traced in when new, traced out at its old pose and
  // in at the new one when it moved past the tolerance, else left where it is. `scan` must
  // be the same scan at every call for one key (it is not stored).
  Placement Place(uint64_t key, const LaserScan& scan, const Pose2& T_map_body);
  // How far keyframe `key`'s far beam ends would move if placed at T_map_body (the measure
  // Place compares with the tolerance); nullopt when it is not placed.
  std::optional<double> Displacement(uint64_t key, const Pose2& T_map_body) const;
  double move_tolerance_m() const { return move_tolerance_m_; }
  // How far from the body origin the scan's beams reach (m): Displacement's lever.
  double ReachFromBody(const LaserScan& scan) const;
  // That of placed keyframe `key`'s scan; nullopt when it is not placed.
  std::optional<double> Reach(uint64_t key) const {
    const auto it = reach_m_.find(key);
    return it == reach_m_.end() ? std::nullopt : std::optional<double>(it->second);
  }
  // Takes keyframe `key` out (`scan`: the one it was placed with); false when not placed.
  bool Remove(uint64_t key, const LaserScan& scan);
  // The grid made again of exactly `keyframes`, each traced once at its pose (what placing,
  // moving and removing would give, in one trace per keyframe instead of two per move: the
  // cheaper way when most placed keyframes moved). Every tile any scan ever reached stays,
  // and every tile is marked changed.
  struct Keyframe {
    uint64_t key;
    const LaserScan* scan;
    Pose2 T_map_body;
  };
  void Rebuild(const std::vector<Keyframe>& keyframes);
  // The pose each placed keyframe was traced at.
  const std::unordered_map<uint64_t, Pose2>& placed() const { return placed_pose_; }

  // Log-odds of a cell; nullopt when no placed scan observes it.
  std::optional<double> LogOdds(int64_t cell_x, int64_t cell_y) const;
  int8_t Occupancy(int64_t cell_x, int64_t cell_y) const;

  // Every tile that any scan ever reached, sorted by (tile_y, tile_x) (a tile whose scans
  // all moved away stays, unknown, so that subscribers learn it emptied).
  std::vector<GridTile> Tiles(int64_t utime, int64_t update) const;
  // The tiles whose cells changed since the last call (or the last ForgetChanges), sorted.
  std::vector<GridTile> TakeChangedTiles(int64_t utime, int64_t update);
  void ForgetChanges() { changed_.clear(); }
  size_t num_tiles() const { return tiles_.size(); }
  size_t num_changed_tiles() const { return changed_.size(); }

 private:
  // A tile's counts, structure of arrays: hits of its size x size cells row by row, then
  // their misses (a row of a trace then adds to two runs of consecutive integers). 16-bit
  // while at most kMaxNarrowPlaced keyframes are placed (no count can exceed the number of
  // placed scans: each adds at most one to a cell), which halves the memory a trace reads
  // and writes; 32-bit beyond (every tile widened once, Reserve).
  struct Tile {
    std::vector<int16_t> narrow;
    std::vector<int32_t> wide;
  };
  static constexpr size_t kMaxNarrowPlaced = 32767;
  // Widens the counts if `placed` keyframes could overflow 16-bit ones.
  void Reserve(size_t placed);
  // Adds (sign +1) or takes out (-1) the cells of `scan` at T_map_body.
  void Trace(const LaserScan& scan, const Pose2& T_map_body, int sign);
  // Takes the scan out at T_map_from and in at T_map_to (two traces; one pass over their rows'
  // counts when the tracer holds both in one window).
  void Move(const LaserScan& scan, const Pose2& T_map_from, const Pose2& T_map_to);
  // The tiles a tracer's window spans.
  struct TileSpan {
    int64_t min_x = 0, min_y = 0, columns = 0, rows = 0;
    int64_t count() const { return columns * rows; }
  };
  TileSpan WindowTiles(const ScanTracer::Window& window) const;
  template <typename Count>
  void TraceRows(const ScanTracer::Window& window, int sign);
  template <typename Count>
  void TraceMoveRows(const ScanTracer::Window& window);
  // Adds `add` to the hits of window cell (wx, wy).
  template <typename Count>
  void AddHit(const ScanTracer::Window& window, const TileSpan& span, int64_t wx, int64_t wy,
              Count add);
  // Adds add(wx) to the misses of each cell wx of window row wy in [first, last]; a tile is
  // touched (made, marked changed) only when traced(wx) is nonzero for one of its cells.
  template <typename Count, typename Traced, typename Add>
  void AddRowMisses(const ScanTracer::Window& window, const TileSpan& span, int64_t wy,
                    int64_t first, int64_t last, Traced traced, Add add);
  // The same when the tracer's window does not apply (rays very long for the cell size):
  // cell by cell, a tile found per cell.
  template <typename Count>
  void TraceCellByCell(const ScanTracer::Window& window, int sign);
  // Tile (tile_x, tile_y)'s counts (hits, then misses at + cells_per_tile_), the tile made
  // when new; marks it changed.
  template <typename Count>
  Count* TouchTile(int64_t tile_x, int64_t tile_y);
  std::optional<double> LogOdds(int32_t hits, int32_t misses) const;
  GridTile Export(uint64_t key, const Tile& tile, int64_t utime, int64_t update) const;
  template <typename Count>
  void ExportCells(const Count* hits, GridTile* tile) const;
  // Occupancy of a cell with these counts (Occupancy's value).
  int8_t CellOccupancy(int32_t hits, int32_t misses) const;

  OccupancyGridOptions options_;
  double move_tolerance_m_;
  ScanTracer tracer_;
  int64_t cells_per_tile_;
  // Per trace, each tile the tracer's window spans, once touched (row-major over the
  // window's tiles): one hash lookup per tile and trace.
  std::vector<void*> window_tiles_;
  bool wide_ = false;
  std::unordered_map<uint64_t, Tile> tiles_;
  std::unordered_set<uint64_t> changed_;
  std::unordered_map<uint64_t, Pose2> placed_pose_;
  std::unordered_map<uint64_t, double> reach_m_;  // from the body origin, per placed key
  // CellOccupancy of hits < kTableHits, misses < kTableMisses (64 KB, made once): what
  // exporting a tile reads for nearly every cell.
  static constexpr int32_t kTableHits = 32, kTableMisses = 2048;
  std::vector<int8_t> small_counts_;
};

}  // namespace anchormap
