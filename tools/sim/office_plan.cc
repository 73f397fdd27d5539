#include "tools/sim/office_plan.h"

#include <algorithm>
#include <cmath>
#include <utility>

namespace anchormap::sim {
namespace {

// Door openings along a wall, as intervals of the wall's running coordinate.
using Doors = std::vector<std::pair<double, double>>;

class TileBuilder {
 public:
  TileBuilder(FloorPlan* plan, Eigen::Vector2d origin, double door_width_m)
      : plan_(plan), origin_(std::move(origin)), half_door_(0.5 * door_width_m) {}

  Doors Door(double center) const { return {{center - half_door_, center + half_door_}}; }
  Doors Door(double center_a, double center_b) const {
    return {{center_a - half_door_, center_a + half_door_},
            {center_b - half_door_, center_b + half_door_}};
  }

  // Wall y = y from x0 to x1, minus the door intervals (in x).
  void Horizontal(double y, double x0, double x1, const Doors& doors = {}) {
    Wall(x0, x1, doors, [&](double x) { return Eigen::Vector2d(x, y); });
  }
  // Wall x = x from y0 to y1, minus the door intervals (in y).
  void Vertical(double x, double y0, double y1, const Doors& doors = {}) {
    Wall(y0, y1, doors, [&](double y) { return Eigen::Vector2d(x, y); });
  }
  void Place(double x, double y, int region, bool is_room) {
    plan_->places.push_back({origin_ + Eigen::Vector2d(x, y), region, is_room});
  }

 private:
  template <typename PointAt>
  void Wall(double from, double to, Doors doors, PointAt point_at) {
    std::sort(doors.begin(), doors.end());
    double start = from;
    for (const auto& [door_from, door_to] : doors) {
      if (door_from > start) Add(point_at(start), point_at(door_from));
      start = std::max(start, door_to);
    }
    if (start < to) Add(point_at(start), point_at(to));
  }
  void Add(const Eigen::Vector2d& a, const Eigen::Vector2d& b) {
    plan_->walls.push_back({origin_ + a, origin_ + b});
  }

  FloorPlan* plan_;
  Eigen::Vector2d origin_;
  double half_door_;
};

void AddTile(int tx, int ty, const OfficePlanOptions& options, FloorPlan* plan) {
  const int region = ty * options.tiles_x + tx;
  TileBuilder b(plan, Eigen::Vector2d(tx * kOfficeTileWidthM, ty * kOfficeTileHeightM),
                options.door_width_m);
  const double w = kOfficeTileWidthM;
  const double h = kOfficeTileHeightM;

  // Outer walls: each tile draws its south and west wall (a door when a neighbour lies
  // beyond), and the north / east wall only on the last row / column.
  b.Horizontal(0.0, 0.0, w, ty > 0 ? b.Door(20.0) : Doors{});
  b.Vertical(0.0, 0.0, h, tx > 0 ? b.Door(11.0) : Doors{});
  if (ty == options.tiles_y - 1) b.Horizontal(h, 0.0, w);
  if (tx == options.tiles_x - 1) b.Vertical(w, 0.0, h);

  // Rooms around the ring corridor [7, 33] x [7, 23]; the ring's inner edge is the
  // central block [9.5, 30.5] x [9.5, 20.5].
  const Doors band_doors = {{8.0, 8.0 + options.door_width_m},
                            {13.5 - 0.5 * options.door_width_m, 13.5 + 0.5 * options.door_width_m},
                            {20.0 - 0.5 * options.door_width_m, 20.0 + 0.5 * options.door_width_m},
                            {26.5 - 0.5 * options.door_width_m, 26.5 + 0.5 * options.door_width_m},
                            {32.0 - options.door_width_m, 32.0}};
  b.Horizontal(7.0, 0.0, w, band_doors);
  b.Horizontal(23.0, 0.0, w, band_doors);
  for (double x : {10.0, 17.0, 23.0, 30.0}) {
    b.Vertical(x, 0.0, 7.0);
    b.Vertical(x, 23.0, h);
  }
  b.Vertical(7.0, 7.0, 23.0, b.Door(11.0, 19.0));
  b.Vertical(33.0, 7.0, 23.0, b.Door(11.0, 19.0));
  b.Horizontal(15.0, 0.0, 7.0);
  b.Horizontal(15.0, 33.0, w);

  // Central block: two halves split by the cross corridor x in [18.75, 21.25], each half
  // split into two rooms at y = 15; doors onto the ring and onto the cross corridor.
  b.Horizontal(9.5, 9.5, 18.75, b.Door(14.1));
  b.Horizontal(20.5, 9.5, 18.75, b.Door(14.1));
  b.Horizontal(9.5, 21.25, 30.5, b.Door(25.9));
  b.Horizontal(20.5, 21.25, 30.5, b.Door(25.9));
  b.Vertical(9.5, 9.5, 20.5);
  b.Vertical(30.5, 9.5, 20.5);
  b.Vertical(18.75, 9.5, 20.5, b.Door(12.25, 17.75));
  b.Vertical(21.25, 9.5, 20.5, b.Door(12.25, 17.75));
  b.Horizontal(15.0, 9.5, 18.75);
  b.Horizontal(15.0, 21.25, 30.5);

  // Room centres (start places and destinations).
  for (double x : {5.0, 13.5, 20.0, 26.5, 35.0}) {
    b.Place(x, 3.5, region, true);
    b.Place(x, 26.5, region, true);
  }
  for (double y : {11.0, 19.0}) {
    b.Place(3.5, y, region, true);
    b.Place(36.5, y, region, true);
  }
  for (double x : {14.1, 25.9}) {
    for (double y : {12.25, 17.75}) b.Place(x, y, region, true);
  }
  // Corridor places: ring corners, ring mid-points, the cross corridor's centre.
  for (double x : {8.25, 20.0, 31.75}) {
    b.Place(x, 8.25, region, false);
    b.Place(x, 21.75, region, false);
  }
  b.Place(8.25, 15.0, region, false);
  b.Place(31.75, 15.0, region, false);
  b.Place(20.0, 15.0, region, false);
}

}  // namespace

Status OfficePlanOptions::Validate() const {
  if (tiles_x < 1 || tiles_y < 1) return Status::Error("office tiles must be at least 1 x 1");
  if (static_cast<long>(tiles_x) * tiles_y > 10000)
    return Status::Error("at most 10000 office tiles");
  if (!(door_width_m >= 0.8 && door_width_m <= 2.0)) {
    return Status::Error("office door width must be in [0.8, 2.0] m");
  }
  return Status::Ok();
}

FloorPlan BuildOfficePlan(const OfficePlanOptions& options) {
  FloorPlan plan;
  plan.regions_x = options.tiles_x;
  plan.regions_y = options.tiles_y;
  for (int ty = 0; ty < options.tiles_y; ++ty) {
    for (int tx = 0; tx < options.tiles_x; ++tx) AddTile(tx, ty, options, &plan);
  }
  return plan;
}

OfficePlanOptions OfficeTilesForRobots(int num_robots, int robots_per_tile) {
  OfficePlanOptions options;
  const int per_tile = std::max(1, robots_per_tile);
  const int tiles = std::max(1, (num_robots + per_tile - 1) / per_tile);
  options.tiles_x = static_cast<int>(std::ceil(std::sqrt(static_cast<double>(tiles))));
  options.tiles_y = (tiles + options.tiles_x - 1) / options.tiles_x;
  return options;
}

}  // namespace anchormap::sim
