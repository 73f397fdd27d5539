#include "tests/testing/random_graph.h"

#include <cmath>
#include <random>

namespace anchormap::testing {

PoseGraph RandomGraph(const RandomGraphOptions& options) {
  std::mt19937 rng(options.seed);
  std::normal_distribution<double> unit(0.0, 1.0);
  std::uniform_real_distribution<double> turn(-0.6, 0.6);
  PoseGraph graph;
  Pose2 pose;
  Eigen::Matrix3d information = Eigen::Matrix3d::Zero();
  information(0, 0) = information(1, 1) = 1.0 / (options.sigma_xy_m * options.sigma_xy_m);
  information(2, 2) = 1.0 / (options.sigma_theta_rad * options.sigma_theta_rad);
  // One draw per statement, last coordinate first: gcc's order of the arguments this once
  // drew in (the order of a call's arguments is unspecified; clang drew other graphs).
  auto noisy = [&](const Pose2& truth) {
    const double theta = truth.theta() + options.sigma_theta_rad * unit(rng);
    const double y = truth.y() + options.sigma_xy_m * unit(rng);
    const double x = truth.x() + options.sigma_xy_m * unit(rng);
    return Pose2(x, y, theta);
  };
  for (int i = 0; i < options.poses; ++i) {
    graph.vertices.push_back({i, pose});
    // Steer back towards the origin beyond the arena radius, so the walk revisits places.
    double heading_change = turn(rng);
    if (pose.translation().norm() > options.arena_radius_m) {
      const double home = std::atan2(-pose.y(), -pose.x());
      heading_change = 0.5 * AngleDifference(home, pose.theta());
    }
    const Pose2 step(1.0, 0.0, heading_change);
    if (i + 1 < options.poses) {
      graph.edges.push_back({i, i + 1, noisy(step), information});
      pose = Compose(pose, step);
    }
  }
  int added = 0;
  for (int attempt = 0; attempt < 100 * options.loop_closures && added < options.loop_closures;
       ++attempt) {
    const int j = std::uniform_int_distribution<int>(2, options.poses - 1)(rng);
    const int i = std::uniform_int_distribution<int>(0, j - 2)(rng);
    const Pose2 truth = Between(graph.vertices[i].pose, graph.vertices[j].pose);
    if (truth.translation().norm() > options.max_loop_distance_m) continue;
    graph.edges.push_back({i, j, noisy(truth), information});
    ++added;
  }
  return graph;
}

}  // namespace anchormap::testing
