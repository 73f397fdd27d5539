#pragma once
// Builds the server's outputs from the current estimate: the merged map (every trajectory,
// anchored or not, its keyframe poses in the global frame), the anchors' marginal
// covariances (from the smoother's R, docs/METHOD.md section 6) and the occupancy grid
// (rebuilt from every keyframe's scan at its current pose, since poses move after every
// update). It also decides when each output is due: the map and covariances after an
// update, at most once per map_period_s; the grid at most once per grid_period_s.
// "now" is whatever clock the caller runs on (wall time online, data time offline).

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "common/scan/occupancy_grid.h"
#include "common/solver/smoother.h"
#include "common/types/map_outputs.h"
#include "common/util/status.h"
#include "server/trajectory_table.h"

namespace anchormap {

struct MapPublisherOptions {
  // Merged map and anchor covariances: after an update, at most this often (0 = after
  // every update).
  double map_period_s = 0.5;
  // Occupancy grid: at most this often, when the map changed (0 = never).
  double grid_period_s = 5.0;
  // The grid covers the largest group of trajectories that share a frame (anchored
  // together, or the largest single unanchored trajectory before any encounter).
  OccupancyGridOptions grid;

  Status Validate() const {
    if (!(map_period_s >= 0)) return Status::Error("publish.map_period_s must be >= 0");
    if (!(grid_period_s >= 0)) return Status::Error("publish.grid_period_s must be >= 0");
    return grid.Validate();
  }
};

class MapPublisher {
 public:
  explicit MapPublisher(const MapPublisherOptions& options = {}) : options_(options) {}
  const MapPublisherOptions& options() const { return options_; }

  MergedMap BuildMergedMap(const Smoother& smoother, const TrajectoryTable& table,
                           const std::vector<EncounterLink>& links, int64_t utime,
                           int64_t update) const;
  // Non-const smoother: covariance recovery memoises inside it.
  AnchorCovariances BuildAnchorCovariances(Smoother* smoother, const TrajectoryTable& table,
                                           int64_t utime, int64_t update) const;
  // Cost: O(keyframes x beams x ray length), the heaviest output; hence its own period.
  std::vector<GridTile> BuildGridTiles(const Smoother& smoother, const TrajectoryTable& table,
                                       int64_t utime, int64_t update) const;
  // The solver trajectories whose keyframes make the grid (see MapPublisherOptions::grid).
  std::vector<TrajectoryId> GridTrajectories(const Smoother& smoother,
                                             const TrajectoryTable& table) const;

  // Rate limiting. `update` is the smoother's update count; nothing is due without a new
  // update since the last publication.
  bool MapDue(int64_t now_utime, int64_t update) const;
  void MarkMapPublished(int64_t now_utime, int64_t update);
  bool GridDue(int64_t now_utime, int64_t update) const;
  void MarkGridPublished(int64_t now_utime, int64_t update);

 private:
  MapPublisherOptions options_;
  std::optional<int64_t> last_map_utime_;
  int64_t last_map_update_ = 0;
  std::optional<int64_t> last_grid_utime_;
  int64_t last_grid_update_ = 0;
};

}  // namespace anchormap
