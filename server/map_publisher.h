#pragma once
// Builds the server's outputs from the current estimate: the merged map (every trajectory,
// anchored or not, its keyframe poses in the global frame), the anchors' marginal
// covariances (from the smoother's R, docs/METHOD.md section 6) and the occupancy grid (a
// KeyframeGrid kept across publications: at each one only the keyframes whose pose moved
// by about a cell are traced again, and only the tiles that changed go out, all of them
// every grid_full_period_s for subscribers that join late). It also decides when each
// output is due: the map after an update, at most once per map_period_s (the covariances
// with it, at most once per anchor_covariances_period_s); the grid at most once per
// grid_period_s.
// "now" is whatever clock the caller runs on (wall time online, data time offline).

#include <cstdint>
#include <optional>
#include <string>
#include <unordered_map>
#include <vector>

#include "common/scan/keyframe_grid.h"
#include "common/scan/occupancy_grid.h"
#include "common/solver/smoother.h"
#include "common/types/map_outputs.h"
#include "common/util/status.h"
#include "server/keyframe_moves.h"
#include "server/map_chunker.h"
#include "server/trajectory_table.h"

namespace anchormap {

struct MapPublisherOptions {
  // Merged map and anchor covariances: after an update, at most this often (0 = after
  // every update).
  double map_period_s = 0.5;
  // The anchor covariances go out with a map at most this often (0 = with every map), and
  // with the first map after the set of anchored trajectories changed, and with every full
  // map (the end of input, the online republication). Each costs one solve per anchor
  // through R's bottom rows, which grow with the map: at 20 robots late in a 900 s run,
  // 3.6 % of the replay's samples when they went with every 0.5 s map (flat21).
  double anchor_covariances_period_s = 2.0;
  // The merged map goes out as a header and the chunks that changed (MapChunker, within its
  // budget of chunks that only moved); every chunk again about this often, for subscribers
  // that joined late or lost a chunk: a share of the chunks, the least recently sent, at
  // every map (the time since the last one over this period), not all of them at once.
  double map_full_period_s = 10.0;
  MapChunkerOptions chunks;
  // Occupancy grid: at most this often, when the map changed (0 = never).
  double grid_period_s = 5.0;
  // Every tile of the grid at most this often (a subscriber that joined late, or lost a
  // tile, has the whole grid within it); the grid publications in between carry only the
  // changed tiles (0 = every grid publication carries every tile).
  double grid_full_period_s = 60.0;
  // A keyframe's scan is traced again when its far beam ends moved more than this many
  // cells since it was traced.
  double grid_move_tolerance_cells = 1.0;
  // At most this many keyframes traced again per grid publication, those that moved
  // farthest first (0: no limit); the others wait for the next publications (new keyframes
  // are always traced in). After a loop closure most of a map moves by a few cells, and
  // tracing it all again at every publication grew with the map: 20 simulated robots spent
  // 15 % of the replay's CPU here by 200 s of data. A complete grid (BuildGridTiles with
  // `complete`) traces every moved keyframe.
  int grid_max_moved = 1000;
  // Within that, a publication traces again at most grid_min_moved plus
  // grid_moved_per_inserted per keyframe it traces in (new to the grid): the work per second
  // of data then follows the keyframes the team adds, not the map. At 20 simulated robots
  // (~150 new keyframes per 5 s) the 1000 bound held from ~150 s of data on, 0.14 CPU s per
  // data second, while most of those keyframes had moved by a few cells only.
  int grid_min_moved = 100;
  double grid_moved_per_inserted = 2.0;
  // The grid covers the largest group of trajectories that share a frame (anchored
  // together, or the largest single unanchored trajectory before any encounter).
  OccupancyGridOptions grid;

  Status Validate() const {
    if (!(map_period_s >= 0)) return Status::Error("publish.map_period_s must be >= 0");
    if (!(map_full_period_s >= 0)) return Status::Error("publish.map_full_period_s must be >= 0");
    if (!(anchor_covariances_period_s >= 0))
      return Status::Error("publish.anchor_covariances_period_s must be >= 0");
    if (chunks.chunk_poses < 1 || chunks.chunk_poses > 65536)
      return Status::Error("publish.chunks.chunk_poses must be 1..65536");
    if (!(chunks.tolerance_m >= 0) || !(chunks.tolerance_rad >= 0))
      return Status::Error("publish.chunks tolerances must be >= 0");
    if (chunks.max_moved_chunks < 0)
      return Status::Error("publish.chunks.max_moved_chunks must be >= 0");
    if (chunks.max_read_chunks < 0)
      return Status::Error("publish.chunks.max_read_chunks must be >= 0");
    if (!(grid_period_s >= 0)) return Status::Error("publish.grid_period_s must be >= 0");
    if (!(grid_full_period_s >= 0)) return Status::Error("publish.grid_full_period_s must be >= 0");
    if (!(grid_move_tolerance_cells >= 0))
      return Status::Error("publish.grid_move_tolerance_cells must be >= 0");
    if (grid_max_moved < 0) return Status::Error("publish.grid_max_moved must be >= 0");
    if (grid_min_moved < 0) return Status::Error("publish.grid_min_moved must be >= 0");
    if (!(grid_moved_per_inserted >= 0))
      return Status::Error("publish.grid_moved_per_inserted must be >= 0");
    return grid.Validate();
  }
};

class MapPublisher {
 public:
  explicit MapPublisher(const MapPublisherOptions& options = {})
      : options_(options),
        chunker_(options.chunks),
        grid_(options.grid, options.grid_move_tolerance_cells) {}
  const MapPublisherOptions& options() const { return options_; }

  MergedMap BuildMergedMap(const Smoother& smoother, const TrajectoryTable& table,
                           const std::vector<EncounterLink>& links, int64_t utime,
                           int64_t update) const;
  // The current estimate's merged map as chunks and a header for the bus
  // (MapChunker::Update): the chunks that changed since the last call within the chunker's
  // budget, and the least recently sent ones in proportion to the time since the last call
  // over map_full_period_s; every chunk when `full`, on the first call, or when that period
  // has passed since the last call. The merged map is not built: only the poses of the
  // chunks the chunker reads are looked up, in the frame the smoother keeps them in (after a
  // full split a subscriber's map holds GlobalTrajectory's bits). The chunker is given each
  // keyframe's node and offset, so that it reads only chunks whose nodes moved.
  MapChunker::Split SplitMergedMap(const Smoother& smoother, const TrajectoryTable& table,
                                   const std::vector<EncounterLink>& links, int64_t utime,
                                   int64_t update, int64_t now_utime, bool full = false);
  // Non-const smoother: it keeps the covariance solves' scratch. Each anchor's marginal is
  // one sparse solve through the rows below it in R (Smoother::ProjectedCovariance).
  AnchorCovariances BuildAnchorCovariances(Smoother* smoother, const TrajectoryTable& table,
                                           int64_t utime, int64_t update) const;
  // The trajectories BuildAnchorCovariances would publish now (anchored, the anchor solved),
  // in the table's order: cheap, no solve.
  std::vector<TrajectoryId> PublishedAnchors(const Smoother& smoother,
                                             const TrajectoryTable& table) const;
  // The grid moved toward the current estimate (UpdateGrid; all the way when `complete`),
  // every tile of it. Cost: that of UpdateGrid plus O(tiles x cells).
  std::vector<GridTile> BuildGridTiles(const Smoother& smoother, const TrajectoryTable& table,
                                       int64_t utime, int64_t update, bool complete = false);
  // The same, only the tiles that changed since the last BuildGridTiles or
  // BuildChangedGridTiles.
  std::vector<GridTile> BuildChangedGridTiles(const Smoother& smoother,
                                              const TrajectoryTable& table, int64_t utime,
                                              int64_t update);
  // Moves the grid to the current estimate: keyframes of the grid's trajectories traced in
  // when new, traced again where they moved past the tolerance (unless `complete` at most
  // grid_min_moved + grid_moved_per_inserted x the keyframes traced in, and never more than
  // grid_max_moved: the farthest moved first, then by trajectory and index), traced
  // out when their trajectory left the grid. The moved keyframes are found by node
  // (KeyframeMoves: a keyframe is its node's pose (+) a fixed offset), the same as a scan of
  // every keyframe would find. Cost: one pose per node plus the keyframes of the nodes that
  // moved (every keyframe when the grid's trajectories change, or `complete`), plus
  // O(beams x ray length) per traced scan, bounded per call by the new keyframes.
  struct GridChange {
    int64_t inserted = 0;
    int64_t moved = 0;
    int64_t removed = 0;
    int64_t deferred = 0;  // moved past the tolerance, left for a later call (the budget)
  };
  GridChange UpdateGrid(const Smoother& smoother, const TrajectoryTable& table,
                        bool complete = false);
  const KeyframeGrid& grid() const { return grid_; }
  // What the grid updates and the map splits cost, counted for the status.
  struct GridWork {
    int64_t updates = 0;
    int64_t inserted = 0;
    int64_t moved = 0;  // traced again
    int64_t deferred = 0;
    int64_t removed = 0;
    int64_t rebuilds = 0;
    int64_t nodes_examined = 0;  // KeyframeMoves' node poses read
    int64_t moves_found = 0;     // keyframes past the tolerance (traced again or deferred)
  };
  const GridWork& grid_work() const { return grid_work_; }
  const MapChunker::Work& chunk_work() const { return chunker_.work(); }
  // Both, one line.
  std::string WorkSummary() const;
  // The solver trajectories whose keyframes make the grid (see MapPublisherOptions::grid).
  std::vector<TrajectoryId> GridTrajectories(const Smoother& smoother,
                                             const TrajectoryTable& table) const;

  // Rate limiting. `update` is the smoother's update count; nothing is due without a new
  // update since the last publication.
  bool MapDue(int64_t now_utime, int64_t update) const;
  void MarkMapPublished(int64_t now_utime, int64_t update);
  bool GridDue(int64_t now_utime, int64_t update) const;
  void MarkGridPublished(int64_t now_utime, int64_t update);
  // Whether the next grid publication should carry every tile (grid_full_period_s).
  bool GridFullDue(int64_t now_utime) const;
  void MarkGridFullPublished(int64_t now_utime) { last_grid_full_utime_ = now_utime; }
  // Whether a map publication now carries the anchor covariances: always with a `full` map,
  // at once when the published anchors differ from the last ones sent, else at most once
  // per anchor_covariances_period_s (`anchors`: PublishedAnchors).
  bool AnchorCovariancesDue(int64_t now_utime, const std::vector<TrajectoryId>& anchors,
                            bool full) const;
  void MarkAnchorCovariancesPublished(int64_t now_utime, std::vector<TrajectoryId> anchors);

 private:
  MapPublisherOptions options_;
  std::optional<int64_t> last_map_utime_;
  int64_t last_map_update_ = 0;
  std::optional<int64_t> last_grid_utime_;
  int64_t last_grid_update_ = 0;
  std::optional<int64_t> last_grid_full_utime_;
  std::optional<int64_t> last_covariances_utime_;
  std::vector<TrajectoryId> last_covariances_anchors_;  // the trajectories they held
  GridChange MoveGrid(const Smoother& smoother, const TrajectoryTable& table, bool complete);
  // The share of the chunks SplitMergedMap sends again whatever changed; `*full` when all.
  double Refresh(int64_t now_utime, bool* full);
  std::optional<int64_t> last_map_split_utime_;
  MapChunker chunker_;
  KeyframeGrid grid_;
  // The grid's keyframes by node, to find those that moved (UpdateGrid), and how many
  // keyframes of each of the grid's trajectories it holds.
  KeyframeMoves moves_{grid_.move_tolerance_m()};
  std::unordered_map<int64_t, int32_t> grid_counts_;  // by solver trajectory
  GridWork grid_work_;
};

}  // namespace anchormap
