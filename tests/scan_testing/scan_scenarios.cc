#include "tests/scan_testing/scan_scenarios.h"

#include <cmath>
#include <random>
#include <stdexcept>

namespace anchormap::testing {

SyntheticWorld LoopWorld() {
  SyntheticWorld world;
  // Outer walls, the block off-centre: a block centred in the room would make the room look
  // the same turned by 180 degrees (the pillars alone do not tell the two apart).
  world.AddBox(0.0, 0.0, 23.0, 16.0);
  world.AddBox(5.0, 4.0, 15.0, 10.0);  // the block the loop goes round
  // Pillars and alcove walls, each of its own size, near the walls.
  world.AddBox(0.6, 2.5, 1.0, 3.1);
  world.AddBox(0.5, 8.0, 1.3, 8.4);
  world.AddBox(9.0, 0.4, 9.5, 1.2);
  world.AddBox(13.0, 0.5, 14.2, 0.9);
  world.AddBox(18.8, 5.5, 19.4, 6.0);
  world.AddBox(18.5, 11.0, 19.0, 12.2);
  world.AddBox(6.0, 13.0, 6.8, 13.5);
  world.AddBox(15.5, 12.8, 16.0, 13.6);
  world.AddBox(3.8, 6.5, 5.0, 6.8);      // a stub on the block's west side
  world.AddBox(11.0, 10.0, 11.3, 10.9);  // on its north side
  world.AddBox(15.0, 7.0, 15.6, 7.4);    // on its east side
  world.AddBox(7.5, 3.4, 8.4, 4.0);      // on its south side
  world.min_corner = {0.0, 0.0};
  world.max_corner = {23.0, 16.0};
  return world;
}

SyntheticWorld TwinCorridorWorld() {
  SyntheticWorld world;
  // Corridor walls: y in [0, 3] and [10, 13], x from 4 to 20, with identical doors' jambs.
  for (double dy : {0.0, 10.0}) {
    world.walls.push_back({{4.0, 0.0 + dy}, {20.0, 0.0 + dy}});
    world.walls.push_back({{4.0, 3.0 + dy}, {20.0, 3.0 + dy}});
    world.walls.push_back({{20.0, 0.0 + dy}, {20.0, 3.0 + dy}});
    for (double x : {8.0, 12.5, 17.0}) {
      world.AddBox(x, 0.0 + dy, x + 0.4, 0.3 + dy);
      world.AddBox(x + 1.0, 2.7 + dy, x + 1.3, 3.0 + dy);
    }
  }
  // The hall joining them: x in [0, 4], y in [0, 13], distinct pillars.
  world.walls.push_back({{0.0, 0.0}, {4.0, 0.0}});
  world.walls.push_back({{0.0, 13.0}, {4.0, 13.0}});
  world.walls.push_back({{0.0, 0.0}, {0.0, 13.0}});
  world.walls.push_back({{4.0, 3.0}, {4.0, 10.0}});
  world.AddBox(1.0, 5.0, 1.6, 5.4);
  world.AddBox(2.2, 8.3, 2.5, 9.2);
  world.min_corner = {0.0, 0.0};
  world.max_corner = {20.0, 13.0};
  return world;
}

SyntheticWorld TurnedHallWorld() {
  SyntheticWorld world;
  // The hall: x in [0, 30], y in [0, 8] (its middle (15, 4)); a 2 m door at the west end of
  // its north wall (x in [1, 3]) and, turned, at the east end of its south wall.
  world.walls.push_back({{0.0, 0.0}, {0.0, 8.0}});
  world.walls.push_back({{30.0, 0.0}, {30.0, 8.0}});
  world.walls.push_back({{0.0, 8.0}, {1.0, 8.0}});
  world.walls.push_back({{3.0, 8.0}, {30.0, 8.0}});
  world.walls.push_back({{0.0, 0.0}, {27.0, 0.0}});
  world.walls.push_back({{29.0, 0.0}, {30.0, 0.0}});
  // Beyond the north door a room with pillars, x in [-6, 8], y in [8, 18]; beyond the south
  // door a bare corridor running east (turned, it would run west above the hall).
  world.walls.push_back({{-6.0, 8.0}, {1.0, 8.0}});
  world.walls.push_back({{3.0, 8.0}, {8.0, 8.0}});
  world.walls.push_back({{-6.0, 8.0}, {-6.0, 18.0}});
  world.walls.push_back({{8.0, 8.0}, {8.0, 18.0}});
  world.walls.push_back({{-6.0, 18.0}, {8.0, 18.0}});
  world.AddBox(-3.0, 11.0, -2.2, 11.8);
  world.AddBox(5.0, 10.5, 5.6, 11.5);
  world.AddBox(-1.0, 15.0, 0.2, 15.5);
  world.AddBox(4.0, 15.5, 4.5, 16.5);
  world.walls.push_back({{27.0, 0.0}, {27.0, -3.0}});
  world.walls.push_back({{29.0, 0.0}, {40.0, 0.0}});
  world.walls.push_back({{27.0, -3.0}, {40.0, -3.0}});
  world.walls.push_back({{40.0, -3.0}, {40.0, 0.0}});
  // Features in pairs turned about (15, 4): (x, y) -> (30 - x, 8 - y).
  const auto pair = [&world](double x0, double y0, double x1, double y1) {
    world.AddBox(x0, y0, x1, y1);
    world.AddBox(30.0 - x1, 8.0 - y1, 30.0 - x0, 8.0 - y0);
  };
  pair(4.0, 0.0, 4.6, 0.6);
  pair(8.0, 7.4, 8.3, 8.0);
  pair(11.0, 0.0, 11.8, 0.3);
  pair(13.5, 7.6, 14.5, 8.0);
  pair(6.5, 2.0, 6.9, 2.4);
  pair(18.0, 0.0, 18.6, 0.5);
  world.min_corner = {-6.0, -3.0};
  world.max_corner = {40.0, 18.0};
  return world;
}

SyntheticWorld PeriodicCorridorWorld() {
  SyntheticWorld world;
  world.AddBox(-10.0, 0.0, 50.0, 13.0);  // outer walls
  world.AddBox(-7.0, 3.0, 47.0, 10.0);   // the block the ring goes round
  for (double x = -8.0; x <= 48.0; x += 8.0) {
    world.AddBox(x, 0.0, x + 0.3, 0.4);
    if (x + 3.0 < 47.0) world.AddBox(x + 3.0, 2.6, x + 3.3, 3.0);
  }
  world.min_corner = {-10.0, 0.0};
  world.max_corner = {50.0, 13.0};
  return world;
}

std::vector<Pose2> RectanglePath(const Eigen::Vector2d& lo, const Eigen::Vector2d& hi,
                                 double step_m, double laps) {
  const Eigen::Vector2d corners[4] = {lo, {hi.x(), lo.y()}, hi, {lo.x(), hi.y()}};
  const double perimeter = 2.0 * ((hi.x() - lo.x()) + (hi.y() - lo.y()));
  const int steps = static_cast<int>(std::floor(laps * perimeter / step_m));
  std::vector<Pose2> path;
  for (int s = 0; s <= steps; ++s) {
    double along = std::fmod(s * step_m, perimeter);
    for (int side = 0; side < 4; ++side) {
      const Eigen::Vector2d a = corners[side], b = corners[(side + 1) % 4];
      const double length = (b - a).norm();
      if (along < length - 1e-9 || side == 3) {
        const Eigen::Vector2d direction = (b - a) / length;
        const Eigen::Vector2d p = a + along * direction;
        path.emplace_back(p.x(), p.y(), std::atan2(direction.y(), direction.x()));
        break;
      }
      along -= length;
    }
  }
  return path;
}

std::vector<Pose2> LoopWorldLap(size_t first, size_t count) {
  const std::vector<Pose2> laps = RectanglePath({2.5, 2.0}, {17.5, 12.0}, 0.5, 2.0);
  if (first + count > laps.size()) throw std::out_of_range("LoopWorldLap: past two laps");
  return std::vector<Pose2>(laps.begin() + static_cast<long>(first),
                            laps.begin() + static_cast<long>(first + count));
}

std::vector<Pose2> StraightPath(const Eigen::Vector2d& from, const Eigen::Vector2d& to,
                                double step_m) {
  const Eigen::Vector2d d = to - from;
  const double heading = std::atan2(d.y(), d.x());
  const int steps = static_cast<int>(std::floor(d.norm() / step_m));
  std::vector<Pose2> path;
  for (int s = 0; s <= steps; ++s) {
    const Eigen::Vector2d p = from + d.normalized() * (s * step_m);
    path.emplace_back(p.x(), p.y(), heading);
  }
  return path;
}

std::vector<Keyframe> DriveKeyframes(const SyntheticWorld& world, const std::vector<Pose2>& path,
                                     const std::string& robot, int64_t trajectory_id,
                                     int64_t start_utime, const OdometryNoise& noise,
                                     uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> normal(0.0, 1.0);
  SyntheticLaser laser;
  std::vector<Keyframe> keyframes;
  Pose2 odometry;
  for (size_t i = 0; i < path.size(); ++i) {
    Keyframe k;
    k.robot = robot;
    k.trajectory_id = trajectory_id;
    k.seq = static_cast<int32_t>(i);
    k.utime = start_utime + static_cast<int64_t>(i) * 500'000;
    if (i > 0) {
      const Pose2 truth = Between(path[i - 1], path[i]);
      // One draw per statement: the order of a call's arguments is unspecified (gcc and
      // clang differ), and the scenario must not depend on the compiler. This order is the
      // one gcc used, so the figures quoted in the tests stay the same.
      const double theta_noise = normal(rng);
      const double y_noise = normal(rng);
      const double x_noise = normal(rng);
      k.T_previous_this =
          Pose2(truth.x() + noise.sigma_xy_m * x_noise, truth.y() + noise.sigma_xy_m * y_noise,
                truth.theta() + noise.bias_theta_rad + noise.sigma_theta_rad * theta_noise);
      k.T_previous_this_covariance =
          Eigen::Vector3d(noise.sigma_xy_m * noise.sigma_xy_m, noise.sigma_xy_m * noise.sigma_xy_m,
                          noise.sigma_theta_rad * noise.sigma_theta_rad)
              .asDiagonal();
      odometry = Compose(odometry, k.T_previous_this);
    }
    k.T_local_pose = odometry;
    k.scan = SimulateScan(world, laser, path[i], &rng);
    keyframes.push_back(std::move(k));
  }
  return keyframes;
}

}  // namespace anchormap::testing
