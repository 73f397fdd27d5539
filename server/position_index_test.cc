#include "server/position_index.h"

#include <cmath>
#include <random>
#include <vector>

#include <gtest/gtest.h>

namespace anchormap {
namespace {

// Every item within the radius, by looking at all of them.
std::vector<int32_t> BruteForce(const std::vector<Eigen::Vector2d>& points,
                                const Eigen::Vector2d& center, double radius) {
  std::vector<int32_t> items;
  for (size_t i = 0; i < points.size(); ++i) {
    if ((points[i] - center).norm() <= radius) items.push_back(static_cast<int32_t>(i));
  }
  return items;
}

TEST(PositionIndexTest, NearFindsExactlyThePointsWithinTheRadius) {
  std::mt19937 random(7);
  std::uniform_real_distribution<double> coordinate(-60.0, 40.0);
  std::vector<Eigen::Vector2d> points;
  PositionIndex index(4.0);
  for (int32_t i = 0; i < 500; ++i) {
    // One draw per statement: a call's argument order is unspecified (gcc's order kept).
    const double y = coordinate(random);
    const double x = coordinate(random);
    points.emplace_back(x, y);
    index.Add(i, points.back());
  }
  EXPECT_EQ(index.size(), 500u);
  int found = 0;
  // Radii below a cell, across cells, and wider than the whole set (every cell is read).
  for (const double radius : {0.0, 0.5, 3.9, 4.0, 9.5, 30.0, 500.0}) {
    for (int q = 0; q < 40; ++q) {
      const double center_y = coordinate(random);
      const double center_x = coordinate(random);
      const Eigen::Vector2d center(center_x, center_y);
      const std::vector<int32_t> near = index.Near(center, radius);
      EXPECT_EQ(near, BruteForce(points, center, radius)) << "radius " << radius;
      found += static_cast<int>(near.size());
    }
  }
  EXPECT_GT(found, 500);  // the queries did find points
  // On a point, radius 0 finds it.
  EXPECT_EQ(index.Near(points[17], 0.0), std::vector<int32_t>{17});
}

TEST(PositionIndexTest, ClearEmptiesAndBadValuesAreIgnored) {
  PositionIndex index(2.0);
  index.Add(0, {1.0, 1.0});
  index.Add(1, {std::nan(""), 0.0});  // not stored
  EXPECT_EQ(index.size(), 1u);
  EXPECT_TRUE(index.Near({1.0, 1.0}, -1.0).empty());
  EXPECT_TRUE(index.Near({std::nan(""), 1.0}, 5.0).empty());
  EXPECT_EQ(index.Near({0.0, 0.0}, 2.0), std::vector<int32_t>{0});
  index.Clear();
  EXPECT_EQ(index.size(), 0u);
  EXPECT_TRUE(index.Near({1.0, 1.0}, 10.0).empty());
  // Negative coordinates far from the origin land in their own cells.
  index.Add(5, {-1000.5, -2000.25});
  EXPECT_EQ(index.Near({-1000.0, -2000.0}, 1.0), std::vector<int32_t>{5});
  EXPECT_TRUE(index.Near({1000.0, 2000.0}, 1.0).empty());
}

}  // namespace
}  // namespace anchormap
