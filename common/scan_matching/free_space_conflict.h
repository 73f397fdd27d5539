#pragma once
// Whether two maps put together by a hypothesised relative pose contradict each other: the
// end points of one side's scans that land where the other side's rays passed (space that
// side saw free, away from every wall it saw). Matching scores only where points land near
// walls; a perceptually aliased place (a look-alike corridor, a symmetric room) can score
// as well as the true one, but beyond the matched walls the wrong map's walls stand in the
// other's open space: its rays pass through them. A true join shows few such points (people,
// doors, the estimates' small errors).
//
// Cells of resolution_m on a grid anchored at the origin (cell (i, j) spans
// [i r, (i + 1) r) x [j r, (j + 1) r)): a cell is seen free when a ray's segment from its
// origin to wall_margin_m short of its end point touches the cell; it is near a wall when an
// end point lies within wall_margin_m of the cell's centre. A point contradicts the map when
// its cell is seen free and not near a wall.

#include <cstddef>
#include <cstdint>
#include <vector>

#include <Eigen/Core>

#include "common/scan_matching/point_cloud.h"

namespace anchormap {

// One scan in a common frame: where the sensor stood and the end points of its returns.
struct RayScan {
  Eigen::Vector2d origin = Eigen::Vector2d::Zero();
  PointCloud end_points;
};

struct FreeSpaceOptions {
  double resolution_m = 0.1;
  // Rays stop this short of their end point, and cells this near an end point are walls:
  // the slack for the estimates' error between two maps joined correctly.
  double wall_margin_m = 0.3;
};

class FreeSpaceMap {
 public:
  FreeSpaceMap(const std::vector<RayScan>& scans, const FreeSpaceOptions& options);

  // The point's cell was seen free and no wall is near it.
  bool Contradicts(const Eigen::Vector2d& point) const;
  // The point's cell was seen at all (free or near a wall).
  bool Seen(const Eigen::Vector2d& point) const;

 private:
  static constexpr uint8_t kFree = 1;
  static constexpr uint8_t kWall = 2;
  uint8_t CellAt(const Eigen::Vector2d& point) const;
  void Mark(int64_t i, int64_t j, uint8_t flag);
  void MarkRay(const Eigen::Vector2d& from, const Eigen::Vector2d& to);

  FreeSpaceOptions options_;
  int64_t min_i_ = 0;
  int64_t min_j_ = 0;
  int64_t width_ = 0;
  int64_t height_ = 0;
  std::vector<uint8_t> cells_;
};

struct FreeSpaceConflict {
  size_t seen = 0;         // points that landed where the map saw anything
  size_t contradicts = 0;  // of those, points in space the map saw free
  double fraction() const {
    return seen == 0 ? 0.0 : static_cast<double>(contradicts) / static_cast<double>(seen);
  }
};

// The end points of `scans` tested against `map`.
FreeSpaceConflict CountFreeSpaceConflicts(const FreeSpaceMap& map,
                                          const std::vector<RayScan>& scans);

}  // namespace anchormap
