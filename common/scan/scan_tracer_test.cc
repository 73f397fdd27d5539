#include "common/scan/scan_tracer.h"

#include <array>
#include <cmath>
#include <map>
#include <random>
#include <utility>

#include <gtest/gtest.h>

#include "common/geometry/angle.h"
#include "common/scan/occupancy_grid.h"

namespace anchormap {
namespace {

using Cell = std::pair<int64_t, int64_t>;

// The cells of `scan` by brute force: each beam's Bresenham line from the sensor's cell to
// its end cell; a cell is a hit when some return within the ray length ends in it, else a
// miss.
std::map<Cell, bool> BruteForceCells(const LaserScan& scan, const Pose2& T_map_body,
                                     const OccupancyGridOptions& options) {
  const Pose2 T_map_sensor = Compose(T_map_body, scan.T_body_sensor);
  auto cell_of = [&](const Eigen::Vector2d& p) {
    return Cell{static_cast<int64_t>(std::floor(p.x() / options.resolution_m)),
                static_cast<int64_t>(std::floor(p.y() / options.resolution_m))};
  };
  const Cell sensor = cell_of(T_map_sensor.translation());
  std::map<Cell, bool> cells;
  std::vector<Cell> hits;
  for (size_t i = 0; i < scan.ranges.size(); ++i) {
    const double angle = scan.Angle(i);
    const Eigen::Vector2d direction(std::cos(angle), std::sin(angle));
    double length = options.max_ray_length_m;
    bool hit = false;
    if (scan.IsReturn(i)) {
      length = std::min<double>(scan.ranges[i], options.max_ray_length_m);
      hit = scan.ranges[i] <= options.max_ray_length_m;
    } else if (!options.no_return_as_free) {
      continue;
    }
    const Cell end = cell_of(T_map_sensor.TransformPoint(length * direction));
    for (const Cell& cell : BresenhamLine(sensor.first, sensor.second, end.first, end.second)) {
      cells.emplace(cell, false);
    }
    if (hit) hits.push_back(end);
  }
  for (const Cell& cell : hits) cells[cell] = true;
  return cells;
}

// A row ForEachMarkedRow or ForEachMoveRow reports: after the last one (`last_row`), inside
// the window, whole aligned groups.
void ExpectAlignedRow(const ScanTracer::Window& window, int64_t wy, int64_t first, int64_t last,
                      int64_t* last_row) {
  EXPECT_GT(wy, *last_row);
  *last_row = wy;
  EXPECT_LE(0, first);
  EXPECT_LE(first, last);
  EXPECT_LT(last, window.side);
  EXPECT_EQ((window.min_x + first) % ScanTracer::kMarkGroup, 0);
  EXPECT_EQ((last - first + 1) % ScanTracer::kMarkGroup, 0);
}

// The marked cells of row wy's [first, last] into `cells` (true: a hit).
void AddMarkedCells(const ScanTracer::Window& window, int64_t wy, int64_t first, int64_t last,
                    const uint8_t* marks, std::map<Cell, bool>* cells) {
  for (int64_t wx = first; wx <= last; ++wx) {
    if (marks[wx] == 0) continue;
    EXPECT_TRUE(marks[wx] == ScanTracer::kHitMark || marks[wx] == ScanTracer::kMissMark);
    (*cells)[{window.min_x + wx, window.min_y + wy}] = marks[wx] == ScanTracer::kHitMark;
  }
}

// Every hit cell among `cells` reported once, and nothing else.
void ExpectHitsReportedOnce(const std::map<Cell, int>& hits, const std::map<Cell, bool>& cells) {
  for (const auto& [cell, hit] : cells) {
    EXPECT_EQ(hits.count(cell) != 0, hit);
    if (hit) {
      EXPECT_EQ(hits.at(cell), 1);
    }
  }
  EXPECT_LE(hits.size(), cells.size());
}

// The cells MarkCells leaves, read through ForEachHit and ForEachMarkedRow; every traced
// cell must lie within its row's reported extent, every row must be reported once, in
// order, and every hit once by ForEachHit.
std::map<Cell, bool> MarkedCells(ScanTracer* tracer, const ScanTracer::Window& window) {
  tracer->MarkCells();
  std::map<Cell, int> hits;
  tracer->ForEachHit([&](int64_t wx, int64_t wy) {
    ++hits[{window.min_x + wx, window.min_y + wy}];
  });
  std::map<Cell, bool> cells;
  int64_t last_row = -1;
  tracer->ForEachMarkedRow([&](int64_t wy, int64_t first, int64_t last, const uint8_t* marks) {
    ExpectAlignedRow(window, wy, first, last, &last_row);
    AddMarkedCells(window, wy, first, last, marks, &cells);
  });
  ExpectHitsReportedOnce(hits, cells);
  return cells;
}

LaserScan RandomScan(std::mt19937_64* rng, int beams, float rad0, float radstep) {
  std::uniform_real_distribution<float> range(0.05f, 7.0f);
  std::uniform_int_distribution<int> kind(0, 9);
  LaserScan scan;
  scan.rad0 = rad0;
  scan.radstep = radstep;
  scan.max_range = 6.5f;
  scan.T_body_sensor = Pose2(0.13, -0.04, 0.2);
  for (int i = 0; i < beams; ++i) {
    const int k = kind(*rng);
    // Returns, returns beyond the ray length (5 m below), no returns, and very short ones.
    scan.ranges.push_back(k == 0 ? 0.0f : k == 1 ? 0.01f : range(*rng));
  }
  return scan;
}

Pose2 RandomPose(std::mt19937_64* rng) {
  std::uniform_real_distribution<double> xy(-3.0, 3.0), theta(-kPi, kPi);
  return Pose2(xy(*rng), xy(*rng), theta(*rng));
}

// Random scans at random poses (every direction, so every octant of the lines; beams along
// the axes and diagonals too), with and without no-returns traced as free space, at 5 cm
// and at 5 mm (beams of up to 1022 cells, the longest a window holds): the marks are
// exactly the cells and flags of the beams' Bresenham lines, and of Trace's list; one
// tracer for all, so each trace also shows the last one's marks were cleared, whether or
// not its rows were read.
TEST(ScanTracerTest, MarksAreTheCellsOfEveryBeamsBresenhamLine) {
  std::mt19937_64 rng(11);
  for (const double resolution_m : {0.05, 0.005}) {
    for (const bool no_return_as_free : {false, true}) {
      OccupancyGridOptions options;
      options.resolution_m = resolution_m;
      options.max_ray_length_m = resolution_m == 0.05 ? 5.0 : 5.11;
      options.no_return_as_free = no_return_as_free;
      ScanTracer tracer, reference;
      int64_t hits = 0, misses = 0;
      const int scans = resolution_m == 0.05 ? 40 : 4;
      for (int n = 0; n < scans; ++n) {
        const LaserScan scan = n % 4 == 0 ? RandomScan(&rng, 8, 0.0f, static_cast<float>(kPi / 4))
                                          : RandomScan(&rng, 361, static_cast<float>(-kPi),
                                                       static_cast<float>(kPi / 180));
        const Pose2 pose = RandomPose(&rng);
        const std::map<Cell, bool> expected = BruteForceCells(scan, pose, options);
        std::map<Cell, bool> listed;
        for (const TracedCell& c : reference.Trace(scan, pose, options)) {
          listed[{c.x, c.y}] = c.hit;
        }
        EXPECT_EQ(listed, expected);
        const std::optional<ScanTracer::Window> window = tracer.Start(scan, pose, options);
        ASSERT_TRUE(window.has_value());
        ASSERT_TRUE(tracer.MarksInWindow());
        if (n % 5 == 3) {
          tracer.MarkCells();  // marks left unread: the next trace clears them
          continue;
        }
        EXPECT_EQ(MarkedCells(&tracer, *window), expected) << "scan " << n;
        for (const auto& [cell, hit] : expected) (hit ? hits : misses) += 1;
      }
      EXPECT_GT(hits, resolution_m == 0.05 ? 4000 : 300);
      EXPECT_GT(misses, 100000);
    }
  }
}

// The two traces a move leaves, read through ForEachMoveHit and ForEachMoveRow, as
// MarkedCells reads one: [0] the trace out, [1] the trace in.
std::array<std::map<Cell, bool>, 2> MovedCells(ScanTracer* tracer,
                                               const ScanTracer::Window& window) {
  tracer->MarkMove();
  std::array<std::map<Cell, int>, 2> hits;
  tracer->ForEachMoveHit([&](int64_t wx, int64_t wy, bool in) {
    ++hits[in ? 1 : 0][{window.min_x + wx, window.min_y + wy}];
  });
  std::array<std::map<Cell, bool>, 2> cells;
  int64_t last_row = -1;
  tracer->ForEachMoveRow(
      [&](int64_t wy, int64_t first, int64_t last, const uint8_t* out, const uint8_t* in) {
        ExpectAlignedRow(window, wy, first, last, &last_row);
        AddMarkedCells(window, wy, first, last, out, &cells[0]);
        AddMarkedCells(window, wy, first, last, in, &cells[1]);
      });
  for (int trace = 0; trace < 2; ++trace) ExpectHitsReportedOnce(hits[trace], cells[trace]);
  return cells;
}

// Random scans moved by random shifts (within the slack and beyond it: then no move window),
// interleaved with single traces on the same tracer: a move's two traces are exactly the
// Bresenham cells of the scan at each pose, and every trace clears the marks the last one
// left, read or not.
TEST(ScanTracerTest, AMovesTwoTracesAreTheCellsOfBothPoses) {
  std::mt19937_64 rng(23);
  std::uniform_real_distribution<double> shift(-1.0, 1.0);
  for (const bool no_return_as_free : {false, true}) {
    OccupancyGridOptions options;
    options.max_ray_length_m = 5.0;
    options.no_return_as_free = no_return_as_free;
    ScanTracer tracer;
    int moves = 0, apart = 0;
    for (int n = 0; n < 40; ++n) {
      const LaserScan scan =
          RandomScan(&rng, 361, static_cast<float>(-kPi), static_cast<float>(kPi / 180));
      const Pose2 from = RandomPose(&rng);
      // Up to 1.6 slacks along each axis (beyond it ~60 % of them), or 20 cm.
      const double scale =
          n % 4 == 0 ? 1.6 * static_cast<double>(ScanTracer::kMoveSlack) * options.resolution_m
                     : 0.2;
      const double dx = scale * shift(rng);
      const double dy = scale * shift(rng);
      const double dtheta = 0.1 * shift(rng);
      const Pose2 to(from.x() + dx, from.y() + dy, from.theta() + dtheta);
      if (n % 3 == 1) {  // a single trace between moves, its marks left unread
        ASSERT_TRUE(tracer.Start(scan, to, options).has_value());
        tracer.MarkCells();
      }
      const std::optional<ScanTracer::Window> window = tracer.StartMove(scan, from, to, options);
      const Pose2 sensor_from = Compose(from, scan.T_body_sensor);
      const Pose2 sensor_to = Compose(to, scan.T_body_sensor);
      const auto cell = [&](double v) {
        return static_cast<int64_t>(std::floor(v / options.resolution_m));
      };
      const bool within =
          std::abs(cell(sensor_to.x()) - cell(sensor_from.x())) <= ScanTracer::kMoveSlack &&
          std::abs(cell(sensor_to.y()) - cell(sensor_from.y())) <= ScanTracer::kMoveSlack;
      ASSERT_EQ(window.has_value(), within) << "scan " << n;
      if (!window) {
        ++apart;
        continue;
      }
      ASSERT_TRUE(tracer.MarksInWindow());
      if (n % 5 == 2) {
        tracer.MarkMove();  // marks left unread: the next trace clears them
        continue;
      }
      const auto cells = MovedCells(&tracer, *window);
      EXPECT_EQ(cells[0], BruteForceCells(scan, from, options)) << "scan " << n;
      EXPECT_EQ(cells[1], BruteForceCells(scan, to, options)) << "scan " << n;
      ++moves;
      // A single trace after a move sees its own cells only.
      const std::optional<ScanTracer::Window> single = tracer.Start(scan, to, options);
      ASSERT_TRUE(single.has_value());
      EXPECT_EQ(MarkedCells(&tracer, *single), BruteForceCells(scan, to, options));
    }
    EXPECT_GT(moves, 15);
    EXPECT_GT(apart, 2);
  }
}

}  // namespace
}  // namespace anchormap
