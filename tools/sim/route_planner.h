#pragma once
// Collision-free routes through a floor plan: a clearance raster (exact Euclidean distance
// transform of the walls, Felzenszwalb & Huttenlocher 2012), A* on its 8-connected cells
// with a cost that keeps robots near corridor centres, and a shortcut pass that turns
// the cell chain into a few straight legs, each of which keeps the required clearance.

#include <string>
#include <vector>

#include <Eigen/Core>

#include "common/util/status.h"
#include "tools/sim/floor_plan.h"
#include "tools/sim/random.h"

namespace anchormap::sim {

struct RoutePlannerOptions {
  double resolution_m = 0.1;  // raster cell size; finer is slower to plan
  // Smallest allowed distance from a robot's centre to any wall (robot radius + margin).
  double clearance_m = 0.45;
  // Cells closer to a wall than this cost more (corridor centring); >= clearance_m.
  double preferred_clearance_m = 1.0;
  double wall_cost_weight = 4.0;  // extra cost factor at the required clearance

  Status Validate() const;  // empty when valid
};

class RoutePlanner {
 public:
  RoutePlanner(const FloorPlan& plan, const RoutePlannerOptions& options);

  // Conservative distance (metres) from `point` to the nearest wall or non-traversable
  // cell; 0 outside the raster.
  double Clearance(const Eigen::Vector2d& point) const;
  bool IsTraversable(const Eigen::Vector2d& point) const {
    return Clearance(point) >= options_.clearance_m;
  }
  // True when every point of the straight line keeps the required clearance.
  bool SegmentIsClear(const Eigen::Vector2d& from, const Eigen::Vector2d& to) const;

  // Waypoints from `start` to `goal` (both included; every straight leg between them is
  // clear), or empty when the goal cannot be reached or either end is not traversable.
  std::vector<Eigen::Vector2d> Plan(const Eigen::Vector2d& start,
                                    const Eigen::Vector2d& goal) const;

  // A uniformly drawn traversable point (rejection sampling; nullopt-like: returns false
  // after `max_attempts` failures).
  bool SampleTraversable(Rng& rng, Eigen::Vector2d* point, int max_attempts = 10000) const;

  // Whether `a` and `b` are in the same connected traversable region.
  bool Connected(const Eigen::Vector2d& a, const Eigen::Vector2d& b) const;

  const RoutePlannerOptions& options() const { return options_; }

 private:
  int CellIndex(const Eigen::Vector2d& point) const;  // -1 outside
  Eigen::Vector2d CellCenter(int index) const;

  RoutePlannerOptions options_;
  Eigen::Vector2d origin_{0.0, 0.0};
  int width_ = 0;
  int height_ = 0;
  std::vector<float> clearance_m_;  // per cell, conservative
  std::vector<int> component_;      // connected traversable region per cell, -1 blocked
};

}  // namespace anchormap::sim
