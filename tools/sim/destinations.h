#pragma once
// Where simulated robots start and where they drive next. In the office, robots start in
// distinct rooms of their home tile and then alternate between rooms and corridor
// junctions (sometimes in a neighbouring tile), so routes cross in the corridors; in a
// PGM world, starts and destinations are random traversable points of one connected region.

#include <vector>

#include <Eigen/Core>

#include "tools/sim/floor_plan.h"
#include "tools/sim/random.h"
#include "tools/sim/route_planner.h"

namespace anchormap::sim {

class Destinations {
 public:
  // `plan` and `planner` must outlive this object.
  Destinations(const FloorPlan& plan, const RoutePlanner& planner);

  // Start positions for `num_robots` robots (robot i lives in region HomeRegion(i));
  // empty when the world has no room for them.
  std::vector<Eigen::Vector2d> StartPositions(int num_robots, Rng& rng) const;
  int HomeRegion(int robot_index) const { return robot_index % num_regions_; }

  // The next destination for a robot at `position`: traversable, connected to `position`
  // and at least 2 m away. Returns false when none is found.
  bool Next(int home_region, const Eigen::Vector2d& position, Rng& rng,
            Eigen::Vector2d* destination) const;

 private:
  bool Usable(const Eigen::Vector2d& position, const Eigen::Vector2d& candidate) const;

  const FloorPlan& plan_;
  const RoutePlanner& planner_;
  int num_regions_ = 1;
  std::vector<std::vector<int>> rooms_by_region_;  // indices into plan_.places
  std::vector<std::vector<int>> corridors_by_region_;
};

}  // namespace anchormap::sim
