#include "common/scan_matching/reference_field.h"

#include <cmath>
#include <limits>
#include <random>

#include <gtest/gtest.h>

#include "common/scan_matching/likelihood_grid.h"

namespace anchormap {
namespace {

double DistanceToPolyline(const Eigen::Vector2d& p, const PointCloud& line) {
  double best = std::numeric_limits<double>::infinity();
  for (size_t i = 0; i + 1 < line.size(); ++i) {
    best = std::min(best, (ClosestPointOnSegment(p, line[i], line[i + 1]) - p).norm());
  }
  return best;
}

TEST(ReferenceFieldTest, CellVectorsPointToTheNearestSurfacePoint) {
  // A bent wall sampled every 10 cm (joined), checked cell by cell against brute force.
  PointCloud wall;
  for (int i = 0; i <= 20; ++i) wall.push_back({0.1 * i, i < 10 ? 0.0 : 0.1 * (i - 10)});
  ReferenceFieldOptions options;
  const ReferenceField field({wall}, options);
  const GridGeometry& g = field.geometry();
  ASSERT_GT(g.width, 0);
  int stored = 0;
  for (int iy = 0; iy < g.height; ++iy) {
    for (int ix = 0; ix < g.width; ++ix) {
      const Eigen::Vector2d c = g.CellCentre(ix, iy);
      const double d = DistanceToPolyline(c, wall);
      Eigen::Vector2d v;
      const bool has = field.NearestVector(ix, iy, &v);
      if (d < options.max_distance_m - 1e-6) {
        ASSERT_TRUE(has) << ix << " " << iy;
        EXPECT_NEAR(v.norm(), d, 1e-6);
        EXPECT_NEAR(DistanceToPolyline(c + v, wall), 0.0, 1e-6);  // lands on the wall
        ++stored;
      } else if (d > options.max_distance_m + 1e-6) {
        EXPECT_FALSE(has);
      }
    }
  }
  EXPECT_GT(stored, 100);
}

TEST(ReferenceFieldTest, JoinsOnlyCloseConsecutiveReturns) {
  ReferenceFieldOptions options;
  options.max_join_gap_m = 0.2;
  // Two points 0.15 m apart are one wall: the middle is on the surface.
  const ReferenceField joined({{{0.0, 0.0}, {0.15, 0.0}}}, options);
  // 0.3 m apart they are two dots: the middle is 0.15 m from both.
  const ReferenceField apart({{{0.0, 0.0}, {0.3, 0.0}}}, options);
  Eigen::Vector2d v;
  ASSERT_TRUE(joined.Interpolate({0.075, 0.01}, &v));
  EXPECT_NEAR(v.norm(), 0.01, 1e-6);
  const Eigen::Vector2i c = apart.geometry().CellOf({0.15, 0.0});
  ASSERT_TRUE(apart.NearestVector(c.x(), c.y(), &v));
  EXPECT_GT(v.norm(), 0.1);
  // Two scans are never joined to each other.
  const ReferenceField two_scans({{{0.0, 0.0}}, {{0.15, 0.0}}}, options);
  const Eigen::Vector2i m = two_scans.geometry().CellOf({0.075, 0.0});
  ASSERT_TRUE(two_scans.NearestVector(m.x(), m.y(), &v));
  EXPECT_GT(v.norm(), 0.05);
}

TEST(ReferenceFieldTest, InterpolationIsExactNearAStraightWallWithItsJacobian) {
  // A wall at 30 degrees: the interpolated vector is the exact point-to-line vector, and its
  // derivative is -n n^T.
  const Eigen::Vector2d dir(std::cos(0.5236), std::sin(0.5236));
  const Eigen::Vector2d n(-dir.y(), dir.x());
  PointCloud wall;
  for (int i = -40; i <= 40; ++i) wall.push_back(0.05 * i * dir);
  const ReferenceField field({wall}, ReferenceFieldOptions{});
  std::mt19937_64 rng(3);
  std::uniform_real_distribution<double> along(-1.5, 1.5);
  std::uniform_real_distribution<double> off(-0.06, 0.06);
  for (int i = 0; i < 200; ++i) {
    // One draw per statement: the operands of an overloaded + are unsequenced (gcc's order
    // kept: the right one first).
    const double o = off(rng);
    const double a = along(rng);
    const Eigen::Vector2d p = a * dir + o * n;
    Eigen::Vector2d v;
    Eigen::Matrix2d J;
    ASSERT_TRUE(field.Interpolate(p, &v, &J));
    const Eigen::Vector2d expected = -n * n.dot(p);
    EXPECT_NEAR((v - expected).norm(), 0.0, 1e-5);
    EXPECT_NEAR((J + n * n.transpose()).norm(), 0.0, 1e-4);
  }
}

TEST(ReferenceFieldTest, LikelihoodIsAGaussianOfTheDistance) {
  const ReferenceField field({{{0.0, 0.0}}}, ReferenceFieldOptions{});
  const double sigma = 0.05;
  const LikelihoodGrid grid(field, sigma);
  const GridGeometry& g = grid.geometry();
  for (int iy = 0; iy < g.height; ++iy) {
    for (int ix = 0; ix < g.width; ++ix) {
      const double d = g.CellCentre(ix, iy).norm();
      const double expected =
          d <= field.options().max_distance_m ? std::exp(-d * d / (2 * sigma * sigma)) : 0.0;
      EXPECT_NEAR(grid.Value(ix, iy), expected, 1e-5);
    }
  }
  EXPECT_EQ(grid.Value(-1, 0), 0.0f);
  EXPECT_EQ(grid.Value(0, g.height), 0.0f);
}

TEST(ReferenceFieldTest, EmptyReference) {
  const ReferenceField field({}, ReferenceFieldOptions{});
  Eigen::Vector2d v;
  EXPECT_EQ(field.num_points(), 0u);
  EXPECT_FALSE(field.NearestVector(0, 0, &v));
  EXPECT_FALSE(field.Interpolate({0.0, 0.0}, &v));
}

}  // namespace
}  // namespace anchormap
