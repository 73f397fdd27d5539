#pragma once
// The search over a lattice of poses (x, y, theta): headings center.theta + k * angle_step,
// translations center + (dx, dy) * resolution. Translations are whole cells, so a heading's
// query points are put into cells once and every translation only shifts their indices; the
// score of a lattice pose is the mean likelihood of the cells its points land in (Olson 2009).
//
// BranchAndBound finds the best lattice pose exactly (the same pose as ExhaustiveSearch) by
// scoring blocks of 2^h x 2^h translations on the max-grid of level h, an upper bound of every
// translation in the block (Hess et al. 2016): blocks are visited best first, depth first, and
// a block whose bound is below the best leaf so far is skipped with all it contains. Above
// blocks of 8 cells, headings are bounded in groups too: 2^h consecutive headings move every
// query point by at most about 2^(h-1) cells from where the middle one puts it, so one score on
// level h + 1, shifted back by that much, bounds the group's 2^h x 2^h blocks (one score for
// 2^h headings where the search without groups scored each heading on a level of its own).

#include <cstdint>
#include <memory>
#include <optional>
#include <vector>

#include <Eigen/Core>

#include "common/geometry/pose2.h"
#include "common/scan_matching/byte_max_grids.h"
#include "common/scan_matching/max_grid_pyramid.h"
#include "common/scan_matching/point_cloud.h"

namespace anchormap {

struct SearchWindow {
  Pose2 center;  // the lattice pose (0, 0, 0)
  double angle_step_rad = 0.01;
  int half_angles = 0;   // |k| <= half_angles
  int half_cells_x = 0;  // |dx| <= half_cells_x
  int half_cells_y = 0;  // |dy| <= half_cells_y
};

struct LatticePose {
  int k = 0;
  int dx = 0;
  int dy = 0;
  double score = 0.0;
};

// The pose of a lattice point.
Pose2 LatticeToPose(const SearchWindow& window, double resolution, const LatticePose& lattice);

// The angle step that moves a point at `max_range_m` by at most one cell of `resolution_m`
// (the chord of the arc), capped at 0.1 rad for short scans.
double AngleStepForRange(double resolution_m, double max_range_m);

// The query's points in cells, one list per heading of the window.
class DiscretisedQuery {
 public:
  DiscretisedQuery(const PointCloud& query, const SearchWindow& window,
                   const GridGeometry& geometry);
  size_t num_points() const { return num_points_; }
  // The cells' bounding box at heading k (empty query: min > max).
  struct Box {
    Eigen::Vector2i min;
    Eigen::Vector2i max;
  };
  const Box& box(int k) const { return boxes_[k + half_angles_]; }
  // The cells of the points at heading k, x and y apart (the vectorised scoring loads eight of
  // each at once), in the query's order.
  const int32_t* xs(int k) const { return xs_.get() + Offset(k); }
  const int32_t* ys(int k) const { return ys_.get() + Offset(k); }

 private:
  size_t Offset(int k) const { return static_cast<size_t>(k + half_angles_) * num_points_; }

  int half_angles_ = 0;
  size_t num_points_ = 0;
  // Every heading's cells in one array each (heading after heading): two allocations per
  // query instead of two per heading (a local match has ~120 headings), left uninitialised
  // until every cell is written (a vector's zeros were a fifth of a query's discretisation).
  std::unique_ptr<int32_t[]> xs_;
  std::unique_ptr<int32_t[]> ys_;
  std::vector<Box> boxes_;
};

// Mean over the query's points of the level's value at their cells shifted by (dx, dy); 0 for
// an empty query.
double ScoreOnLevel(const MaxGridPyramid& grids, int level, const DiscretisedQuery& query, int k,
                    int dx, int dy);
// ScoreOnLevel when that is above `floor`; otherwise a value at most `floor` (the scoring stops
// once the points left cannot lift the mean above it). Branch and bound asks every node only
// whether it beats the best leaf so far.
double ScoreOnLevelAbove(const MaxGridPyramid& grids, int level, const DiscretisedQuery& query,
                         int k, int dx, int dy, double floor);

// max |a[i] - b[i]| over i < n, 0 for none: how far any point's cell moves along one axis
// between two headings (a heading group's deviation; exposed for tests).
int MaxCellMove(const int32_t* a, const int32_t* b, size_t n);

struct LatticeSearchStats {
  // Scores computed (any level), as the eager descent computes them: every root counted, lazy
  // roots (BranchAndBound) scored or not (the loop budget's measure of a search's size).
  int64_t scored_nodes = 0;
  int64_t leaves = 0;  // level-0 scores computed
};

// The best lattice pose with a score above min_score (the first in (k, dy, dx) order among
// equals), or nullopt. Evaluates every lattice pose: the reference for tests.
std::optional<LatticePose> ExhaustiveSearch(const MaxGridPyramid& grids,
                                            const DiscretisedQuery& query,
                                            const SearchWindow& window, double min_score,
                                            LatticeSearchStats* stats = nullptr);

// Whether branch and bound bounds its inner nodes on ByteMaxGrids of `grids` for `query`: its
// sums are exact (then a node's mean on the bytes bounds every leaf's float score, bit for bit).
bool ByteBoundsApply(const MaxGridPyramid& grids, const DiscretisedQuery& query);

// The same best lattice pose, by branch and bound over all the pyramid's levels. With `bytes`
// (ByteMaxGrids of `grids`, used when ByteBoundsApply) the inner nodes are bounded on the bytes:
// the same best pose, from slightly looser bounds, so the nodes scored may differ; then only
// the grids' level 0 is read (its levels above need not be built). With
// `centre_first`, the window's centre (a local match's guess) is scored before any node: a
// good guess's score prunes from the first node on (the same best pose; the nodes scored
// differ). With `lazy_roots`, roots on single headings (a pyramid too shallow for heading
// groups, bounded on the floats) are bounded only where groups of them, bounded on two levels
// built above the top, may beat the best leaf: the same pose, nodes below the roots and stats
// (every root counted) as without (the reference for tests).
std::optional<LatticePose> BranchAndBound(const MaxGridPyramid& grids,
                                          const DiscretisedQuery& query, const SearchWindow& window,
                                          double min_score, LatticeSearchStats* stats = nullptr,
                                          const ByteMaxGrids* bytes = nullptr,
                                          bool centre_first = false, bool lazy_roots = true);

}  // namespace anchormap
