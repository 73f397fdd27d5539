#pragma once
// A picture of a simulation's ground truth: the walls, every robot's true path in its
// colour (the same colours anchormap-render uses) and the true positions of each
// encounter. For checking a world and its routes before running the mapping system.

#include <string>
#include <vector>

#include <Eigen/Core>

#include "common/util/status.h"
#include "tools/sim/world.h"

namespace anchormap::sim {

struct SimTrace {
  std::vector<std::vector<Eigen::Vector2d>> paths;  // per robot, at the laser's times
  std::vector<std::pair<Eigen::Vector2d, Eigen::Vector2d>> encounters;  // observer, observed
};

Status WriteSimPreviewPng(const World& world, const SimTrace& trace, const std::string& path,
                          double pixels_per_m = 0.0);

}  // namespace anchormap::sim
