#include "common/scan/keyframe_grid.h"

#include <cmath>
#include <map>
#include <random>
#include <set>

#include <gtest/gtest.h>

#include "common/geometry/angle.h"
#include "common/scan/occupancy_grid.h"

namespace anchormap {
namespace {

// A scan from inside a 12 m x 8 m box centred on the origin, taken at T_map_body (the
// sensor 0.2 m ahead of the body), with a few beams without return.
LaserScan BoxScan(const Pose2& T_map_body, int beams) {
  LaserScan scan;
  scan.T_body_sensor = Pose2(0.2, 0.0, 0.0);
  scan.rad0 = static_cast<float>(-kPi);
  scan.radstep = static_cast<float>(2 * kPi / beams);
  scan.max_range = 30.0f;
  const Pose2 T_map_sensor = Compose(T_map_body, scan.T_body_sensor);
  for (int i = 0; i < beams; ++i) {
    const double angle = T_map_sensor.theta() + scan.Angle(static_cast<size_t>(i));
    const Eigen::Vector2d o = T_map_sensor.translation();
    const Eigen::Vector2d d(std::cos(angle), std::sin(angle));
    double range = 1e9;
    for (int axis = 0; axis < 2; ++axis) {
      const double half = axis == 0 ? 6.0 : 4.0;
      for (double wall : {-half, half}) {
        if (std::abs(d[axis]) < 1e-12) continue;
        const double t = (wall - o[axis]) / d[axis];
        if (t > 0) range = std::min(range, t);
      }
    }
    scan.ranges.push_back(i % 17 == 5 ? 40.0f : static_cast<float>(range));
  }
  return scan;
}

OccupancyGridOptions SmallOptions() {
  OccupancyGridOptions options;
  options.resolution_m = 0.1;
  options.tile_size_cells = 16;
  options.max_ray_length_m = 9.0;
  return options;
}

// Every cell either grid holds, compared: same log-odds (sums of the same counts) or both
// unknown.
void ExpectSameCells(const KeyframeGrid& a, const KeyframeGrid& b) {
  std::set<std::pair<int32_t, int32_t>> tiles;
  for (const auto* grid : {&a, &b}) {
    for (const GridTile& t : grid->Tiles(0, 0)) tiles.insert({t.tile_x, t.tile_y});
  }
  const int64_t size = a.options().tile_size_cells;
  int64_t compared = 0, observed = 0;
  for (const auto& [tx, ty] : tiles) {
    for (int64_t y = ty * size; y < (ty + 1) * size; ++y) {
      for (int64_t x = tx * size; x < (tx + 1) * size; ++x) {
        const auto la = a.LogOdds(x, y), lb = b.LogOdds(x, y);
        ASSERT_EQ(la.has_value(), lb.has_value()) << "cell " << x << " " << y;
        if (la) {
          EXPECT_NEAR(*la, *lb, 1e-9) << "cell " << x << " " << y;
          ++observed;
        }
        ++compared;
      }
    }
  }
  EXPECT_GT(observed, 1000);
  EXPECT_GT(compared, observed);
}

// The same tiles in the same order with the same cells.
void ExpectSameTiles(const std::vector<GridTile>& expected, const std::vector<GridTile>& actual) {
  ASSERT_EQ(actual.size(), expected.size());
  for (size_t i = 0; i < expected.size(); ++i) {
    EXPECT_EQ(actual[i].tile_x, expected[i].tile_x);
    EXPECT_EQ(actual[i].tile_y, expected[i].tile_y);
    EXPECT_EQ(actual[i].cells, expected[i].cells);
  }
}

// A pose in the box's inner part, any heading (one draw per statement: a call's argument
// order is unspecified; gcc's order kept).
Pose2 PoseInBox(std::mt19937* rng) {
  std::uniform_real_distribution<double> x(-4.5, 4.5), y(-3.0, 3.0), theta(-kPi, kPi);
  const double pose_theta = theta(*rng);
  const double pose_y = y(*rng);
  const double pose_x = x(*rng);
  return Pose2(pose_x, pose_y, pose_theta);
}

// With the tiles found through the tracer's window (few tiles per window) and per cell
// (rays long for the tile size: 77 x 77 tiles span the window of the second options).
TEST(KeyframeGridTest, OneScanHasTheCellsOfTheOccupancyGrid) {
  OccupancyGridOptions many_tiles = SmallOptions();
  many_tiles.resolution_m = 0.02;
  many_tiles.tile_size_cells = 8;
  many_tiles.max_ray_length_m = 6.0;
  for (const OccupancyGridOptions& options : {SmallOptions(), many_tiles}) {
    const Pose2 pose(1.0, -0.5, 0.3);
    const LaserScan scan = BoxScan(pose, 360);
    OccupancyGrid reference(options);
    reference.InsertScan(scan, pose);
    KeyframeGrid grid(options);
    EXPECT_EQ(grid.Place(7, scan, pose), KeyframeGrid::Placement::kInserted);
    const std::vector<GridTile> expected = reference.Tiles(3, 4), actual = grid.Tiles(3, 4);
    ASSERT_GT(expected.size(), 20u);
    ExpectSameTiles(expected, actual);
    EXPECT_EQ(grid.TakeChangedTiles(3, 4).size(), expected.size());
  }
}

// Random keyframes in the box, then rounds of random pose moves (small ones below the
// tolerance, large ones past it) and removals: the grid equals one built from scratch at
// the poses it holds, and those are within the tolerance of the true poses.
TEST(KeyframeGridTest, MovedScansGiveTheGridBuiltFromScratch) {
  const OccupancyGridOptions options = SmallOptions();
  std::mt19937 rng(12);
  std::uniform_real_distribution<double> x(-4.5, 4.5), y(-3.0, 3.0), theta(-kPi, kPi);
  std::normal_distribution<double> small(0.0, 0.01), large(0.0, 0.3);
  KeyframeGrid grid(options);
  std::map<uint64_t, Pose2> truth;
  std::map<uint64_t, LaserScan> scans;
  for (uint64_t key = 0; key < 40; ++key) {
    // One draw per statement: a call's argument order is unspecified (gcc's order kept).
    const double pose_theta = theta(rng);
    const double pose_y = y(rng);
    const double pose_x = x(rng);
    const Pose2 pose(pose_x, pose_y, pose_theta);
    scans[key] = BoxScan(pose, 180);
    truth[key] = pose;
    ASSERT_EQ(grid.Place(key, scans[key], pose), KeyframeGrid::Placement::kInserted);
  }
  int moved = 0, unchanged = 0;
  for (int round = 0; round < 6; ++round) {
    for (auto& [key, pose] : truth) {
      const bool big = std::uniform_int_distribution<int>(0, 3)(rng) == 0;
      auto& noise = big ? large : small;
      const double noise_theta = 0.1 * noise(rng);
      const double noise_y = noise(rng);
      const double noise_x = noise(rng);
      pose = Pose2(pose.x() + noise_x, pose.y() + noise_y, pose.theta() + noise_theta);
      const auto placement = grid.Place(key, scans[key], pose);
      (placement == KeyframeGrid::Placement::kMoved ? moved : unchanged) += 1;
    }
    // Take one out.
    const uint64_t key = truth.begin()->first + static_cast<uint64_t>(round);
    if (truth.count(key)) {
      EXPECT_TRUE(grid.Remove(key, scans[key]));
      EXPECT_FALSE(grid.Remove(key, scans[key]));
      truth.erase(key);
    }
  }
  EXPECT_GT(moved, 30);
  EXPECT_GT(unchanged, 30);
  ASSERT_EQ(grid.placed().size(), truth.size());
  KeyframeGrid scratch(options);
  for (const auto& [key, pose] : grid.placed()) {
    // The pose it holds is within about a cell of the truth at the far beam ends.
    const Pose2& actual = truth.at(key);
    const double reach = 9.0 + 0.2;
    EXPECT_LE((pose.translation() - actual.translation()).norm() +
                  std::abs(AngleDifference(pose.theta(), actual.theta())) * reach,
              options.resolution_m + 1e-12);
    scratch.Place(key, scans.at(key), pose);
  }
  ExpectSameCells(grid, scratch);
}

// Made again from a list, a grid equals the one that placed, moved and removed the same
// keyframes one by one: the same tiles (also those every scan left), the same cells, the
// same placed poses; every tile is marked changed.
TEST(KeyframeGridTest, RebuildEqualsMovingAndRemovingOneByOne) {
  const OccupancyGridOptions options = SmallOptions();
  std::mt19937 rng(5);
  std::normal_distribution<double> move(0.0, 0.4);
  KeyframeGrid one_by_one(options), rebuilt(options);
  std::vector<LaserScan> scans;
  std::vector<Pose2> poses;
  for (uint64_t key = 0; key < 30; ++key) {
    poses.push_back(PoseInBox(&rng));
    scans.push_back(BoxScan(poses.back(), 180));
    one_by_one.Place(key, scans.back(), poses.back());
    rebuilt.Place(key, scans.back(), poses.back());
  }
  // Every third keyframe leaves, the others move (most past the tolerance); two new ones.
  std::vector<KeyframeGrid::Keyframe> keyframes;
  for (uint64_t key = 0; key < 30; ++key) {
    if (key % 3 == 0) {
      ASSERT_TRUE(one_by_one.Remove(key, scans[key]));
      continue;
    }
    const double move_theta = 0.1 * move(rng);
    const double move_y = move(rng);
    const double move_x = move(rng);
    const Pose2 pose(poses[key].x() + move_x, poses[key].y() + move_y,
                     poses[key].theta() + move_theta);
    one_by_one.Place(key, scans[key], pose);
    keyframes.push_back({key, &scans[key], one_by_one.placed().at(key)});
  }
  for (uint64_t key = 30; key < 32; ++key) {
    poses.emplace_back(0.5 * static_cast<double>(key - 30), 1.0, 0.2);
    scans.push_back(BoxScan(poses.back(), 180));
  }
  for (uint64_t key = 30; key < 32; ++key) {
    one_by_one.Place(key, scans[key], poses[key]);
    keyframes.push_back({key, &scans[key], poses[key]});
  }
  rebuilt.ForgetChanges();
  rebuilt.Rebuild(keyframes);
  EXPECT_EQ(rebuilt.num_changed_tiles(), rebuilt.num_tiles());
  EXPECT_EQ(rebuilt.placed().size(), one_by_one.placed().size());
  for (const auto& [key, pose] : one_by_one.placed()) {
    EXPECT_EQ(rebuilt.placed().at(key).translation(), pose.translation());
    EXPECT_EQ(rebuilt.placed().at(key).theta(), pose.theta());
    EXPECT_EQ(rebuilt.Displacement(key, pose), 0.0);
  }
  const std::vector<GridTile> expected = one_by_one.Tiles(0, 0), actual = rebuilt.Tiles(0, 0);
  ASSERT_GT(expected.size(), 20u);
  ExpectSameTiles(expected, actual);
  ExpectSameCells(one_by_one, rebuilt);
}

// Past 32767 placed keyframes the counts no longer fit 16 bits: they are widened, and a cell
// seen by every scan still counts them all (a wrapped count would turn a wall free).
TEST(KeyframeGridTest, CountsStayExactPastSixteenBits) {
  OccupancyGridOptions options = SmallOptions();
  options.max_ray_length_m = 0.5;
  LaserScan scan;
  scan.rad0 = 0.0f;
  scan.radstep = static_cast<float>(kPi / 2);
  scan.max_range = 1.0f;
  scan.ranges = {0.35f, 0.25f, 0.45f, 0.3f};
  const Pose2 pose(0.02, 0.03, 0.1);
  KeyframeGrid one(options), three(options), many(options);
  one.Place(0, scan, pose);
  for (uint64_t key = 0; key < 3; ++key) three.Place(key, scan, pose);
  constexpr uint64_t kMany = 32767 + 10;
  for (uint64_t key = 0; key < kMany; ++key) many.Place(key, scan, pose);
  const std::vector<GridTile> tiles = one.Tiles(0, 0);
  ASSERT_EQ(many.Tiles(0, 0).size(), tiles.size());
  const int64_t size = options.tile_size_cells;
  int hits = 0, misses = 0;
  for (const GridTile& tile : tiles) {
    for (int64_t y = tile.tile_y * size; y < (tile.tile_y + 1) * size; ++y) {
      for (int64_t x = tile.tile_x * size; x < (tile.tile_x + 1) * size; ++x) {
        const auto single = one.LogOdds(x, y);
        if (!single) {
          EXPECT_FALSE(many.LogOdds(x, y).has_value());
          continue;
        }
        const bool hit = *single > 0;
        (hit ? hits : misses) += 1;
        EXPECT_EQ(many.LogOdds(x, y), hit ? options.log_odds_max : options.log_odds_min);
      }
    }
  }
  EXPECT_EQ(hits, 4);
  EXPECT_GT(misses, 8);
  for (uint64_t key = 3; key < kMany; ++key) ASSERT_TRUE(many.Remove(key, scan));
  const std::vector<GridTile> expected = three.Tiles(0, 0), actual = many.Tiles(0, 0);
  ExpectSameTiles(expected, actual);
}

// Exported cells are Occupancy's value of their counts, inside and beyond the export's table of
// small counts (hits < 32, misses < 2048), clamped or not (weak log-odds: never clamped).
TEST(KeyframeGridTest, ExportedCellsAreOccupancyInsideAndBeyondTheTable) {
  OccupancyGridOptions clamped = SmallOptions();
  OccupancyGridOptions weak = SmallOptions();
  weak.log_odds_hit = 0.013;
  weak.log_odds_miss = -0.0021;
  weak.log_odds_min = -100.0;
  weak.log_odds_max = 100.0;
  for (const OccupancyGridOptions& options : {clamped, weak}) {
    for (int copies : {1, 3, 40, 2100}) {
      KeyframeGrid grid(options);
      std::mt19937 rng(copies);
      // `copies` scans at one pose (counts up to copies) and a few elsewhere (mixed counts).
      const Pose2 pose(1.0, -0.5, 0.3);
      const LaserScan scan = BoxScan(pose, 90);
      uint64_t key = 0;
      for (int i = 0; i < copies; ++i) grid.Place(key++, scan, pose);
      for (int i = 0; i < 5; ++i) {
        const Pose2 other = PoseInBox(&rng);
        grid.Place(key++, BoxScan(other, 90), other);
      }
      const int64_t size = options.tile_size_cells;
      int64_t observed = 0, between = 0;
      for (const GridTile& tile : grid.Tiles(0, 0)) {
        for (int64_t y = 0; y < size; ++y) {
          for (int64_t x = 0; x < size; ++x) {
            const int64_t cx = tile.tile_x * size + x, cy = tile.tile_y * size + y;
            ASSERT_EQ(tile.cells[static_cast<size_t>(y * size + x)], grid.Occupancy(cx, cy))
                << "copies " << copies << " cell " << cx << " " << cy;
            const auto log_odds = grid.LogOdds(cx, cy);
            observed += log_odds.has_value();
            between +=
                log_odds && *log_odds > options.log_odds_min && *log_odds < options.log_odds_max;
          }
        }
      }
      EXPECT_GT(observed, 500);
      if (&options == &weak) {
        EXPECT_EQ(between, observed);
      }
    }
  }
}

// A subscriber that holds the first full export and applies every batch of changed tiles
// holds the full export at the end; untouched tiles are not re-sent.
TEST(KeyframeGridTest, ChangedTilesBringASubscriberUpToDate) {
  const OccupancyGridOptions options = SmallOptions();
  KeyframeGrid grid(options);
  std::vector<LaserScan> scans;
  std::vector<Pose2> poses;
  for (int i = 0; i < 6; ++i) {
    poses.emplace_back(-4.0 + 1.5 * i, 0.0, 0.0);
    scans.push_back(BoxScan(poses.back(), 180));
    grid.Place(static_cast<uint64_t>(i), scans.back(), poses.back());
  }
  std::map<std::pair<int32_t, int32_t>, std::vector<int8_t>> subscriber;
  for (const GridTile& t : grid.Tiles(0, 1)) subscriber[{t.tile_x, t.tile_y}] = t.cells;
  grid.ForgetChanges();
  EXPECT_TRUE(grid.TakeChangedTiles(0, 1).empty());
  // A pose that moves less than a cell changes nothing.
  EXPECT_EQ(grid.Place(0, scans[0], Compose(poses[0], Pose2(0.03, 0.0, 0.001))),
            KeyframeGrid::Placement::kUnchanged);
  EXPECT_TRUE(grid.TakeChangedTiles(0, 2).empty());
  // A keyframe that moves 0.5 m changes the tiles its rays reach, not all of them.
  EXPECT_EQ(grid.Place(5, scans[5], Compose(poses[5], Pose2(0.0, 0.5, 0.0))),
            KeyframeGrid::Placement::kMoved);
  const std::vector<GridTile> changed = grid.TakeChangedTiles(0, 3);
  EXPECT_GT(changed.size(), 0u);
  EXPECT_LT(changed.size(), grid.num_tiles());
  for (const GridTile& t : changed) subscriber[{t.tile_x, t.tile_y}] = t.cells;
  grid.Remove(2, scans[2]);
  for (const GridTile& t : grid.TakeChangedTiles(0, 4)) subscriber[{t.tile_x, t.tile_y}] = t.cells;
  const std::vector<GridTile> full = grid.Tiles(0, 4);
  ASSERT_EQ(subscriber.size(), full.size());
  for (const GridTile& t : full) EXPECT_EQ(subscriber.at({t.tile_x, t.tile_y}), t.cells);
}

// A move is one pass over both traces' rows (when the sensor moved little) or two traces:
// either way the grid publishes exactly what taking the scan out at its old pose and in at
// its new one (Remove, then Place) publishes, round after round: the same changed tiles with
// the same cells, and at the end the same tiles.
TEST(KeyframeGridTest, AMoveChangesWhatTakingOutAndPuttingInChanges) {
  OccupancyGridOptions options = SmallOptions();
  options.resolution_m = 0.05;
  std::mt19937 rng(31);
  // Moves of a few cells, of metres, and past the tracer's slack (two traces then).
  const double slack_m = static_cast<double>(ScanTracer::kMoveSlack) * options.resolution_m;
  std::normal_distribution<double> small(0.0, 0.1), large(0.0, 1.5), far(0.0, 1.5 * slack_m);
  KeyframeGrid moving(options), out_and_in(options);
  std::vector<Pose2> poses;
  std::vector<LaserScan> scans;
  for (uint64_t key = 0; key < 30; ++key) {
    poses.push_back(PoseInBox(&rng));
    scans.push_back(BoxScan(poses.back(), 180));
    moving.Place(key, scans.back(), poses.back());
    out_and_in.Place(key, scans.back(), poses.back());
  }
  ExpectSameTiles(out_and_in.TakeChangedTiles(0, 0), moving.TakeChangedTiles(0, 0));
  int moved = 0;
  for (int round = 0; round < 5; ++round) {
    for (uint64_t key = 0; key < poses.size(); ++key) {
      if (std::uniform_int_distribution<int>(0, 2)(rng) == 0) continue;
      const int kind = std::uniform_int_distribution<int>(0, 5)(rng);
      auto& noise = kind == 0 ? far : kind == 1 ? large : small;
      const double noise_theta = 0.05 * noise(rng);
      const double noise_y = noise(rng);
      const double noise_x = noise(rng);
      const Pose2& pose = poses[key];
      poses[key] = Pose2(pose.x() + noise_x, pose.y() + noise_y, pose.theta() + noise_theta);
      if (moving.Place(key, scans[key], poses[key]) == KeyframeGrid::Placement::kMoved) {
        ++moved;
        ASSERT_TRUE(out_and_in.Remove(key, scans[key]));
        out_and_in.Place(key, scans[key], poses[key]);
      } else {
        poses[key] = moving.placed().at(key);
      }
    }
    ExpectSameTiles(out_and_in.TakeChangedTiles(0, round), moving.TakeChangedTiles(0, round));
  }
  EXPECT_GT(moved, 50);
  ExpectSameTiles(out_and_in.Tiles(0, 9), moving.Tiles(0, 9));
  ExpectSameCells(moving, out_and_in);
}

}  // namespace
}  // namespace anchormap
