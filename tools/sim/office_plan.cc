#include "tools/sim/office_plan.h"

#include <algorithm>
#include <cmath>
#include <utility>

#include "tools/sim/random.h"

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

// What makes one tile unlike the others and unlike its own half-turn: where the walls between
// rooms stand, where each door sits along its wall, furniture in room corners and cabinets
// along the ring corridor. Real buildings are not exact periodic lattices; an exactly
// repeated tile (and the tile's point symmetry about its centre) would make places that no
// scan can tell apart.
class TileVariation {
 public:
  TileVariation(const OfficePlanOptions& options, int region)
      : rng_(options.seed, static_cast<uint64_t>(region), RngStream::kOfficeLayout),
        varied_(options.varied_tiles) {}

  bool varied() const { return varied_; }
  // `nominal`, or a uniform draw in [low, high] when the tile is varied.
  double Jitter(double nominal, double low, double high) {
    return varied_ ? rng_.Uniform(low, high) : nominal;
  }
  Rng& rng() { return rng_; }

 private:
  Rng rng_;
  bool varied_;
};

// A closed rectangle [x0, x1] x [y0, y1] (tile frame) as four walls.
void AddBox(TileBuilder& b, double x0, double y0, double x1, double y1) {
  b.Horizontal(y0, x0, x1);
  b.Horizontal(y1, x0, x1);
  b.Vertical(x0, y0, y1);
  b.Vertical(x1, y0, y1);
}

// A room corner (x, y) and the directions (+-1, +-1) into the room.
struct Corner {
  double x;
  double y;
  double sx;
  double sy;
};

// Furniture in a room's corners: each corner with probability 0.6 (and one drawn corner
// when none was), a box 0.5-1.5 m along one wall and 0.4-0.9 m deep. The corners given are
// away from the room's doors, so a box never narrows a way in.
void FurnishRoom(TileBuilder& b, TileVariation& v, std::initializer_list<Corner> corners) {
  Rng& rng = v.rng();
  auto box = [&](const Corner& c) {
    const double long_side = rng.Uniform(0.5, 1.5);
    const double short_side = rng.Uniform(0.4, 0.9);
    const bool along_x = rng.Bernoulli(0.5);
    const double dx = c.sx * (along_x ? long_side : short_side);
    const double dy = c.sy * (along_x ? short_side : long_side);
    AddBox(b, std::min(c.x, c.x + dx), std::min(c.y, c.y + dy), std::max(c.x, c.x + dx),
           std::max(c.y, c.y + dy));
  };
  bool any = false;
  for (const Corner& c : corners) {
    if (!rng.Bernoulli(0.6)) continue;
    box(c);
    any = true;
  }
  if (!any) box(*(corners.begin() + rng.Index(corners.size())));
}

// Cabinets 0.2-0.4 m deep and 0.6-1.8 m long against one side of a straight corridor wall
// from `from` to `to` (running coordinate), none within 0.4 m of a keep-out interval (doors,
// openings, corridor places) or of another cabinet. `side` is +1 or -1: into which
// half-plane of the wall they stand. `horizontal`: the wall is y = `at`, else x = `at`.
void AddCabinets(TileBuilder& b, TileVariation& v, bool horizontal, double at, double from,
                 double to, double side, Doors keep_out) {
  Rng& rng = v.rng();
  const int count = static_cast<int>(rng.Index(3));  // 0-2 per wall
  for (int i = 0; i < count; ++i) {
    for (int attempt = 0; attempt < 20; ++attempt) {
      const double length = rng.Uniform(0.6, 1.8);
      const double depth = rng.Uniform(0.2, 0.4);
      const double start = rng.Uniform(from, to - length);
      const double end = start + length;
      bool clear = true;
      for (const auto& [a, c] : keep_out) clear = clear && (end + 0.4 <= a || start - 0.4 >= c);
      if (!clear) continue;
      keep_out.push_back({start, end});
      const double face = at + side * depth;
      if (horizontal) {
        AddBox(b, start, std::min(at, face), end, std::max(at, face));
      } else {
        AddBox(b, std::min(at, face), start, std::max(at, face), end);
      }
      break;
    }
  }
}

void AddTile(int tx, int ty, const OfficePlanOptions& options, FloorPlan* plan) {
  const int region = ty * options.tiles_x + tx;
  TileBuilder b(plan, Eigen::Vector2d(tx * kOfficeTileWidthM, ty * kOfficeTileHeightM),
                options.door_width_m);
  TileVariation v(options, region);
  const double w = kOfficeTileWidthM;
  const double h = kOfficeTileHeightM;
  const double door = options.door_width_m;
  const double half_door = 0.5 * door;

  // Outer walls: each tile draws its south and west wall (a door when a neighbour lies
  // beyond), and the north / east wall only on the last row / column. These doors stay
  // where they are: the neighbour's corner furniture is placed knowing them.
  b.Horizontal(0.0, 0.0, w, ty > 0 ? b.Door(20.0) : Doors{});
  b.Vertical(0.0, 0.0, h, tx > 0 ? b.Door(11.0) : Doors{});
  if (ty == options.tiles_y - 1) b.Horizontal(h, 0.0, w);
  if (tx == options.tiles_x - 1) b.Vertical(w, 0.0, h);

  // Rooms around the ring corridor [7, 33] x [7, 23]; the ring's inner edge is the
  // central block [9.5, 30.5] x [9.5, 20.5]. In a varied tile every room has its own size
  // (the walls between rooms move by up to 1.5 m: a room's own walls are most of what a
  // robot in it sees, so furniture alone leaves rooms alike) and its own door place.
  // South and north bands: five rooms each, split at x = `split` (nominal 10, 17, 23, 30;
  // the middle room keeps the door between tiles at x = 20 clear of its corner boxes).
  struct Band {
    double split[4];
    Doors doors;
  };
  auto band = [&]() {
    Band band{{v.Jitter(10.0, 9.5, 11.5), v.Jitter(17.0, 16.0, 17.5), v.Jitter(23.0, 22.5, 24.0),
               v.Jitter(30.0, 28.5, 30.5)},
              {}};
    const double edges[6] = {0.0, band.split[0], band.split[1], band.split[2], band.split[3], w};
    const double nominal[5] = {8.8, 13.5, 20.0, 26.5, 31.2};
    for (int i = 0; i < 5; ++i) {
      // Onto the ring [7, 33], 0.4 m clear of the room's side walls.
      const double low = std::max(edges[i], 7.0) + half_door + 0.4;
      const double high = std::min(edges[i + 1], 33.0) - half_door - 0.4;
      const double centre = v.Jitter(nominal[i], low, high);
      band.doors.push_back({centre - half_door, centre + half_door});
    }
    return band;
  };
  const Band south = band();
  const Band north = band();
  b.Horizontal(7.0, 0.0, w, south.doors);
  b.Horizontal(23.0, 0.0, w, north.doors);
  for (double x : south.split) b.Vertical(x, 0.0, 7.0);
  for (double x : north.split) b.Vertical(x, 23.0, h);
  // West and east: two rooms each, split at y = 15 (varied by up to 1.5 m).
  const double west_split = v.Jitter(15.0, 13.5, 16.5);
  const double east_split = v.Jitter(15.0, 13.5, 16.5);
  const double west_low = v.Jitter(11.0, 8.4, west_split - 1.2);
  const double west_high = v.Jitter(19.0, west_split + 1.2, 21.6);
  const double east_low = v.Jitter(11.0, 8.4, east_split - 1.2);
  const double east_high = v.Jitter(19.0, east_split + 1.2, 21.6);
  b.Vertical(7.0, 7.0, 23.0, b.Door(west_low, west_high));
  b.Vertical(33.0, 7.0, 23.0, b.Door(east_low, east_high));
  b.Horizontal(west_split, 0.0, 7.0);
  b.Horizontal(east_split, 33.0, w);

  // Central block: two halves split by the cross corridor x in [18.75, 21.25], each half
  // split into two rooms at y = 15 (varied by up to 1.5 m); doors onto the ring and onto
  // the cross corridor.
  const double block_w_split = v.Jitter(15.0, 13.5, 16.5);
  const double block_e_split = v.Jitter(15.0, 13.5, 16.5);
  const double block_sw = v.Jitter(14.1, 11.0, 17.2);
  const double block_nw = v.Jitter(14.1, 11.0, 17.2);
  const double block_se = v.Jitter(25.9, 22.8, 29.0);
  const double block_ne = v.Jitter(25.9, 22.8, 29.0);
  b.Horizontal(9.5, 9.5, 18.75, b.Door(block_sw));
  b.Horizontal(20.5, 9.5, 18.75, b.Door(block_nw));
  b.Horizontal(9.5, 21.25, 30.5, b.Door(block_se));
  b.Horizontal(20.5, 21.25, 30.5, b.Door(block_ne));
  b.Vertical(9.5, 9.5, 20.5);
  b.Vertical(30.5, 9.5, 20.5);
  b.Vertical(18.75, 9.5, 20.5,
             b.Door(v.Jitter(12.25, 10.7, block_w_split - 1.2),
                    v.Jitter(17.75, block_w_split + 1.2, 19.3)));
  b.Vertical(21.25, 9.5, 20.5,
             b.Door(v.Jitter(12.25, 10.7, block_e_split - 1.2),
                    v.Jitter(17.75, block_e_split + 1.2, 19.3)));
  b.Horizontal(block_w_split, 9.5, 18.75);
  b.Horizontal(block_e_split, 21.25, 30.5);

  if (v.varied()) {
    // Room furniture, in the corners of the wall opposite each room's door (the outer
    // wall's doors between tiles are at x = 20 and y = 11, clear of these boxes).
    for (const Band* side : {&south, &north}) {
      const double y = side == &south ? 0.0 : h;
      const double sy = side == &south ? +1.0 : -1.0;
      const double edges[6] = {0.0, side->split[0], side->split[1], side->split[2], side->split[3],
                               w};
      for (int i = 0; i < 5; ++i) {
        FurnishRoom(b, v, {{edges[i], y, +1.0, sy}, {edges[i + 1], y, -1.0, sy}});
      }
    }
    FurnishRoom(b, v, {{0.0, 7.0, +1.0, +1.0}, {0.0, west_split, +1.0, -1.0}});
    FurnishRoom(b, v, {{0.0, west_split, +1.0, +1.0}, {0.0, 23.0, +1.0, -1.0}});
    FurnishRoom(b, v, {{w, 7.0, -1.0, +1.0}, {w, east_split, -1.0, -1.0}});
    FurnishRoom(b, v, {{w, east_split, -1.0, +1.0}, {w, 23.0, -1.0, -1.0}});
    // Central rooms: the corner on the block's outer wall at the split touches no door.
    FurnishRoom(b, v, {{9.5, block_w_split, +1.0, -1.0}});
    FurnishRoom(b, v, {{9.5, block_w_split, +1.0, +1.0}});
    FurnishRoom(b, v, {{30.5, block_e_split, -1.0, -1.0}});
    FurnishRoom(b, v, {{30.5, block_e_split, -1.0, +1.0}});

    // Cabinets along the ring's straight stretches, clear of doors, of the cross
    // corridor's mouths and of the corridor places at its mid-points.
    auto keep_out = [&](const Doors& doors, std::initializer_list<double> places) {
      Doors out = doors;
      for (double p : places) out.push_back({p - 1.5, p + 1.5});
      return out;
    };
    AddCabinets(b, v, true, 7.0, 9.5, 30.5, +1.0, keep_out(south.doors, {20.0}));
    AddCabinets(b, v, true, 23.0, 9.5, 30.5, -1.0, keep_out(north.doors, {20.0}));
    AddCabinets(b, v, false, 7.0, 9.5, 20.5, +1.0, keep_out(b.Door(west_low, west_high), {15.0}));
    AddCabinets(b, v, false, 33.0, 9.5, 20.5, -1.0, keep_out(b.Door(east_low, east_high), {15.0}));
    AddCabinets(b, v, true, 9.5, 9.5, 30.5, -1.0,
                keep_out(b.Door(block_sw, block_se), {18.75, 20.0, 21.25}));
    AddCabinets(b, v, true, 20.5, 9.5, 30.5, +1.0,
                keep_out(b.Door(block_nw, block_ne), {18.75, 20.0, 21.25}));
  }

  // Room centres (start places and destinations).
  for (const Band* side : {&south, &north}) {
    const double y = side == &south ? 3.5 : 26.5;
    const double edges[6] = {0.0, side->split[0], side->split[1], side->split[2], side->split[3],
                             w};
    for (int i = 0; i < 5; ++i) b.Place(0.5 * (edges[i] + edges[i + 1]), y, region, true);
  }
  b.Place(3.5, 0.5 * (7.0 + west_split), region, true);
  b.Place(3.5, 0.5 * (west_split + 23.0), region, true);
  b.Place(36.5, 0.5 * (7.0 + east_split), region, true);
  b.Place(36.5, 0.5 * (east_split + 23.0), region, true);
  b.Place(14.1, 0.5 * (9.5 + block_w_split), region, true);
  b.Place(14.1, 0.5 * (block_w_split + 20.5), region, true);
  b.Place(25.9, 0.5 * (9.5 + block_e_split), region, true);
  b.Place(25.9, 0.5 * (block_e_split + 20.5), region, true);
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
