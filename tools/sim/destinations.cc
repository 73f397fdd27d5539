#include "tools/sim/destinations.h"

namespace anchormap::sim {
namespace {

constexpr double kMinTripM = 2.0;
constexpr double kCorridorProbability = 0.5;   // next stop is a corridor junction
constexpr double kNeighbourProbability = 0.2;  // next stop is in a neighbouring tile

}  // namespace

Destinations::Destinations(const FloorPlan& plan, const RoutePlanner& planner)
    : plan_(plan), planner_(planner), num_regions_(std::max(1, plan.regions_x * plan.regions_y)) {
  rooms_by_region_.resize(num_regions_);
  corridors_by_region_.resize(num_regions_);
  for (size_t i = 0; i < plan_.places.size(); ++i) {
    const Place& place = plan_.places[i];
    if (place.region < 0 || place.region >= num_regions_) continue;
    if (!planner_.IsTraversable(place.position)) continue;
    (place.is_room ? rooms_by_region_ : corridors_by_region_)[place.region].push_back(
        static_cast<int>(i));
  }
}

bool Destinations::Usable(const Eigen::Vector2d& position, const Eigen::Vector2d& candidate) const {
  return (candidate - position).norm() >= kMinTripM && planner_.IsTraversable(candidate) &&
         planner_.Connected(position, candidate);
}

std::vector<Eigen::Vector2d> Destinations::StartPositions(int num_robots, Rng& rng) const {
  std::vector<Eigen::Vector2d> starts;
  if (plan_.places.empty()) {
    // PGM world: the first start fixes the connected region of everybody else.
    for (int i = 0; i < num_robots; ++i) {
      Eigen::Vector2d point;
      bool found = false;
      for (int attempt = 0; attempt < 1000 && !found; ++attempt) {
        if (!planner_.SampleTraversable(rng, &point)) return {};
        found = starts.empty() || planner_.Connected(starts.front(), point);
      }
      if (!found) return {};
      starts.push_back(point);
    }
    return starts;
  }
  // Office: distinct rooms of the home tile in a shuffled order; beyond the rooms, robots
  // share rooms at a small offset.
  std::vector<std::vector<int>> order = rooms_by_region_;
  for (auto& rooms : order) {
    for (size_t i = rooms.size(); i > 1; --i) std::swap(rooms[i - 1], rooms[rng.Index(i)]);
  }
  std::vector<size_t> used(num_regions_, 0);
  for (int i = 0; i < num_robots; ++i) {
    const std::vector<int>& rooms = order[HomeRegion(i)];
    if (rooms.empty()) return {};
    const size_t k = used[HomeRegion(i)]++;
    Eigen::Vector2d point = plan_.places[rooms[k % rooms.size()]].position;
    if (k >= rooms.size()) {
      // One draw per statement: a call's argument order is unspecified, and the simulator's
      // streams must not depend on the compiler (gcc's order kept: y, then x).
      const double dy = rng.Uniform(-1.0, 1.0);
      const double dx = rng.Uniform(-1.0, 1.0);
      const Eigen::Vector2d shifted = point + Eigen::Vector2d(dx, dy);
      if (planner_.IsTraversable(shifted) && planner_.Connected(point, shifted)) point = shifted;
    }
    starts.push_back(point);
  }
  return starts;
}

bool Destinations::Next(int home_region, const Eigen::Vector2d& position, Rng& rng,
                        Eigen::Vector2d* destination) const {
  for (int attempt = 0; attempt < 100; ++attempt) {
    if (plan_.places.empty()) {
      Eigen::Vector2d point;
      if (planner_.SampleTraversable(rng, &point) && Usable(position, point)) {
        *destination = point;
        return true;
      }
      continue;
    }
    int region = home_region;
    if (num_regions_ > 1 && rng.Bernoulli(kNeighbourProbability)) {
      const int rx = home_region % plan_.regions_x;
      const int ry = home_region / plan_.regions_x;
      const int dx[4] = {1, -1, 0, 0};
      const int dy[4] = {0, 0, 1, -1};
      const int k = static_cast<int>(rng.Index(4));
      const int nx = rx + dx[k];
      const int ny = ry + dy[k];
      if (nx >= 0 && ny >= 0 && nx < plan_.regions_x && ny < plan_.regions_y) {
        region = ny * plan_.regions_x + nx;
      }
    }
    const bool corridor = rng.Bernoulli(kCorridorProbability);
    const std::vector<int>& candidates =
        corridor ? corridors_by_region_[region] : rooms_by_region_[region];
    if (candidates.empty()) continue;
    const Eigen::Vector2d point = plan_.places[candidates[rng.Index(candidates.size())]].position;
    if (Usable(position, point)) {
      *destination = point;
      return true;
    }
  }
  return false;
}

}  // namespace anchormap::sim
