#include "common/scan_matching/reference_field.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <memory>
#include <random>
#include <vector>

#include <gtest/gtest.h>
#include <Eigen/Eigenvalues>

#include "common/scan_matching/avx2_dispatch.h"
#include "common/scan_matching/likelihood_grid.h"
#include "common/scan_matching/max_grid_pyramid.h"

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

// Three noisy scans (walls, corners, lone returns, repeated points, segments at every angle):
// every cell of the field equals the definition evaluated cell by cell over all primitives in
// order - the same float vector, the same primitive - whatever rows, columns or vector lanes
// the build visits.
void ExpectCellsHoldTheNearestPrimitive() {
  std::mt19937_64 rng(7);
  std::normal_distribution<double> noise(0.0, 0.01);
  std::vector<PointCloud> scans(3);
  for (int s = 0; s < 3; ++s) {
    for (int i = 0; i < 240; ++i) {
      const double angle = 0.02 * i + 0.7 * s;
      const double range = (i % 37 == 0) ? 0.9 : 1.5 + 0.4 * std::cos(3.0 * angle) + noise(rng);
      scans[s].push_back({range * std::cos(angle) + 0.2 * s, range * std::sin(angle)});
      if (i % 53 == 0) scans[s].push_back(scans[s].back());  // a zero-length segment
    }
  }
  ReferenceFieldOptions options;
  options.max_join_gap_m = 0.1;
  const ReferenceField field(scans, options);
  const GridGeometry& g = field.geometry();
  // The primitives in build order: each vertex's segment to the next when joined, else alone.
  std::vector<std::pair<int, int>> primitives;
  int first = 0;
  for (const PointCloud& scan : scans) {
    for (size_t i = 0; i < scan.size(); ++i) {
      const int a = first + static_cast<int>(i);
      const bool joined =
          i + 1 < scan.size() &&
          (scan[i + 1] - scan[i]).squaredNorm() <= options.max_join_gap_m * options.max_join_gap_m;
      primitives.emplace_back(a, joined ? a + 1 : a);
    }
    first += static_cast<int>(scan.size());
  }
  const float max_sq = static_cast<float>(options.max_distance_m * options.max_distance_m);
  int stored = 0;
  for (int iy = 0; iy < g.height; ++iy) {
    for (int ix = 0; ix < g.width; ++ix) {
      const Eigen::Vector2d centre = g.CellCentre(ix, iy);
      float best = max_sq;
      int best_primitive = -1;
      Eigen::Vector2d best_v;
      for (size_t k = 0; k < primitives.size(); ++k) {
        const Eigen::Vector2d v = ClosestPointOnSegment(centre, field.vertex(primitives[k].first),
                                                        field.vertex(primitives[k].second)) -
                                  centre;
        const float sq = static_cast<float>(v.squaredNorm());
        if (sq <= best) {
          best = sq;
          best_primitive = static_cast<int>(k);
          best_v = v;
        }
      }
      Eigen::Vector2d v;
      int a = 0;
      int b = 0;
      ASSERT_EQ(field.NearestVector(ix, iy, &v), best_primitive >= 0) << ix << " " << iy;
      if (best_primitive < 0) continue;
      ++stored;
      ASSERT_EQ(v.x(), static_cast<double>(static_cast<float>(best_v.x()))) << ix << " " << iy;
      ASSERT_EQ(v.y(), static_cast<double>(static_cast<float>(best_v.y()))) << ix << " " << iy;
      ASSERT_TRUE(field.NearestPrimitive(ix, iy, &a, &b));
      EXPECT_EQ(a, primitives[static_cast<size_t>(best_primitive)].first);
      EXPECT_EQ(b, primitives[static_cast<size_t>(best_primitive)].second);
    }
  }
  EXPECT_GT(stored, 2000);
}

TEST(ReferenceFieldTest, CellsHoldTheNearestPrimitiveToTheBitWithTiesToTheLater) {
  ExpectCellsHoldTheNearestPrimitive();
#ifdef ANCHORMAP_AVX2_DISPATCH
  // Where the CPU has AVX-512 the build above ran its eight-lane path: the AVX2 one too.
  if (CpuHasAvx512()) {
    Avx512Allowed() = false;
    ExpectCellsHoldTheNearestPrimitive();
    Avx512Allowed() = true;
  }
#endif
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

TEST(ReferenceFieldTest, InterpolateInCellIsInterpolateAndCellOfToTheBit) {
  // Random points over the grid and past its edges, and points on cell borders and centres
  // (where floor and the half-cell shift meet): the same vector to the bit, the same cell.
  PointCloud wall;
  for (int i = 0; i <= 30; ++i) wall.push_back({0.1 * i, 0.02 * i * (i % 7 == 0 ? 1 : -1)});
  const ReferenceField field({wall}, ReferenceFieldOptions{});
  const GridGeometry& g = field.geometry();
  std::mt19937_64 rng(11);
  std::uniform_real_distribution<double> x(g.origin.x() - 0.2, g.max_corner().x() + 0.2);
  std::uniform_real_distribution<double> y(g.origin.y() - 0.2, g.max_corner().y() + 0.2);
  std::vector<Eigen::Vector2d> points;
  for (int i = 0; i < 20000; ++i) points.emplace_back(x(rng), y(rng));
  for (int ix = 0; ix <= g.width; ++ix) {
    for (int iy = 0; iy <= g.height; iy += 3) {
      points.push_back(g.origin + g.resolution * Eigen::Vector2d(ix, iy));
      points.push_back(g.CellCentre(ix, iy));
    }
  }
  int inside = 0;
  for (const Eigen::Vector2d& p : points) {
    Eigen::Vector2d v_plain;
    Eigen::Vector2d v;
    Eigen::Vector2i cell;
    const bool plain = field.Interpolate(p, &v_plain);
    ASSERT_EQ(field.InterpolateInCell(p, &v, &cell), plain) << p.transpose();
    if (!plain) continue;
    ++inside;
    EXPECT_EQ(v.x(), v_plain.x());
    EXPECT_EQ(v.y(), v_plain.y());
    EXPECT_EQ(cell, g.CellOf(p)) << p.transpose();
  }
  EXPECT_GT(inside, 1000);
}

// The batch's answers are each point's single calls' (InterpolateInCell, NearestNormal), to the
// bit, wherever a point is found; over a wall and lone returns.
void ExpectSingleCallsAnswers(const ReferenceField& field, ReferenceField::Lookups lookups) {
  field.InterpolateWithNormals(&lookups);
  int found = 0;
  int with_normal = 0;
  for (size_t i = 0; i < lookups.qx.size(); ++i) {
    const Eigen::Vector2d p(lookups.qx[i], lookups.qy[i]);
    Eigen::Vector2d v = Eigen::Vector2d::Zero();
    Eigen::Vector2i cell = Eigen::Vector2i::Zero();
    const bool inside = field.InterpolateInCell(p, &v, &cell);
    ASSERT_EQ(lookups.found[i] != 0, inside) << p.transpose();
    if (!inside) continue;
    ++found;
    EXPECT_EQ(lookups.vx[i], v.x());
    EXPECT_EQ(lookups.vy[i], v.y());
    Eigen::Vector2d n = Eigen::Vector2d::Zero();
    const bool has_normal = field.NearestNormal(cell.x(), cell.y(), &n);
    ASSERT_EQ(lookups.has_normal[i] != 0, has_normal) << p.transpose();
    if (!has_normal) continue;
    ++with_normal;
    EXPECT_EQ(lookups.nx[i], n.x());
    EXPECT_EQ(lookups.ny[i], n.y());
  }
  EXPECT_GT(with_normal, 1000);
  EXPECT_GT(found - with_normal, 100);
}

TEST(ReferenceFieldTest, InterpolateWithNormalsIsInterpolateInCellAndNearestNormalToTheBit) {
  // A wall (joined returns: normals) and lone returns (none), points over the grid, past its
  // edges, on cell borders and centres, and not finite; an odd count (the last points go one
  // at a time): the batch gives each point's single calls' answers to the bit.
  PointCloud scan;
  for (int i = 0; i <= 30; ++i) scan.push_back({0.1 * i, 0.02 * i * (i % 7 == 0 ? 1 : -1)});
  for (int i = 0; i < 5; ++i) scan.push_back({0.5 * i, 1.5 + 0.1 * (i % 2)});
  const ReferenceField field({scan}, ReferenceFieldOptions{});
  const GridGeometry& g = field.geometry();
  std::mt19937_64 rng(12);
  std::uniform_real_distribution<double> x(g.origin.x() - 0.2, g.max_corner().x() + 0.2);
  std::uniform_real_distribution<double> y(g.origin.y() - 0.2, g.max_corner().y() + 0.2);
  ReferenceField::Lookups lookups;
  for (int i = 0; i < 20001; ++i) {
    lookups.qx.push_back(x(rng));
    lookups.qy.push_back(y(rng));
  }
  for (int ix = 0; ix <= g.width; ++ix) {
    for (int iy = 0; iy <= g.height; iy += 3) {
      for (const Eigen::Vector2d& p :
           {Eigen::Vector2d(g.origin + g.resolution * Eigen::Vector2d(ix, iy)),
            g.CellCentre(ix, iy)}) {
        lookups.qx.push_back(p.x());
        lookups.qy.push_back(p.y());
      }
    }
  }
  for (const double bad : {std::nan(""), std::numeric_limits<double>::infinity(),
                           -std::numeric_limits<double>::infinity()}) {
    lookups.qx.push_back(bad);
    lookups.qy.push_back(0.0);
    lookups.qx.push_back(0.5);
    lookups.qy.push_back(bad);
  }
  // Every count modulo 8 (the batch's last points go four, then one at a time), on each vector
  // path the CPU has.
  const std::vector<double> all_x = lookups.qx;
  const std::vector<double> all_y = lookups.qy;
  std::vector<bool> avx512_allowed = {true};
#ifdef ANCHORMAP_AVX2_DISPATCH
  if (CpuHasAvx512()) avx512_allowed.push_back(false);
#endif
  for (const bool allowed : avx512_allowed) {
#ifdef ANCHORMAP_AVX2_DISPATCH
    Avx512Allowed() = allowed;
#endif
    for (size_t count = all_x.size() - 7; count <= all_x.size(); ++count) {
      SCOPED_TRACE(testing::Message() << "AVX-512 allowed " << allowed << ", " << count);
      lookups.qx.assign(all_x.end() - static_cast<std::ptrdiff_t>(count), all_x.end());
      lookups.qy.assign(all_y.end() - static_cast<std::ptrdiff_t>(count), all_y.end());
      lookups.resize(count);
      ExpectSingleCallsAnswers(field, lookups);
    }
  }
#ifdef ANCHORMAP_AVX2_DISPATCH
  Avx512Allowed() = true;
#endif
  // An empty field finds nothing.
  const ReferenceField empty(std::vector<PointCloud>{}, ReferenceFieldOptions{});
  empty.InterpolateWithNormals(&lookups);
  for (size_t i = 0; i < lookups.qx.size(); ++i) EXPECT_EQ(lookups.found[i], 0);
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

// Three noisy scans over a room: walls, corners, lone returns and repeated points.
std::vector<PointCloud> NoisyRoomScans(uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> noise(0.0, 0.01);
  std::vector<PointCloud> scans(3);
  for (int s = 0; s < 3; ++s) {
    for (int i = 0; i < 360; ++i) {
      const double angle = 0.0175 * i + 0.3 * s;
      const double range = (i % 41 == 0) ? 1.2 : 4.0 + 2.0 * std::cos(2.0 * angle) + noise(rng);
      scans[s].push_back({range * std::cos(angle) + 0.3 * s, range * std::sin(angle) - 0.1 * s});
      if (i % 53 == 0) scans[s].push_back(scans[s].back());  // a zero-length segment
    }
  }
  return scans;
}

TEST(ReferenceFieldTest, ForEachStoredVisitsEveryStoredCellOnceWithItsVector) {
  // A room of 12 m across: most of the grid's tiles hold nothing and are skipped; the cells
  // visited are exactly those StoredVector finds in a scan of every cell, each once.
  for (const uint64_t seed : {1, 2}) {
    const ReferenceField field(NoisyRoomScans(seed), ReferenceFieldOptions{});
    const GridGeometry& g = field.geometry();
    std::vector<int> visits(g.num_cells(), 0);
    field.ForEachStored([&](size_t i, float x, float y) {
      ASSERT_LT(i, g.num_cells());
      ++visits[i];
      float sx = 0.0f;
      float sy = 0.0f;
      ASSERT_TRUE(field.StoredVector(i, &sx, &sy));
      EXPECT_EQ(x, sx);
      EXPECT_EQ(y, sy);
    });
    size_t stored = 0;
    for (size_t i = 0; i < g.num_cells(); ++i) {
      float x = 0.0f;
      float y = 0.0f;
      const bool has = field.StoredVector(i, &x, &y);
      ASSERT_EQ(visits[i], has ? 1 : 0) << i;
      stored += has ? 1 : 0;
    }
    EXPECT_GT(stored, 5000u);
    EXPECT_LT(stored, g.num_cells() / 4);
  }
}

TEST(ReferenceFieldTest, TheScansNormalsAreTheirSurfacesToTheBit) {
  // Built from the scans, a field makes the normals of the vertices its cells' primitives use
  // only; built from the scans' surfaces it takes every one. Every cell reads the same
  // primitive, the same normals (the primitive's, its two vertices') to the bit.
  ReferenceFieldOptions options;
  options.max_join_gap_m = 0.15;
  const std::vector<PointCloud> scans = NoisyRoomScans(3);
  std::vector<std::shared_ptr<const ScanSurface>> surfaces;
  for (const PointCloud& scan : scans) {
    surfaces.push_back(
        std::make_shared<const ScanSurface>(MakeScanSurface(scan, options.max_join_gap_m)));
  }
  const ReferenceField from_scans(scans, options);
  const ReferenceField from_surfaces(surfaces, options);
  const GridGeometry& g = from_scans.geometry();
  ASSERT_EQ(g.width, from_surfaces.geometry().width);
  ASSERT_EQ(g.height, from_surfaces.geometry().height);
  int with_normal = 0;
  int lone = 0;
  for (int iy = 0; iy < g.height; ++iy) {
    for (int ix = 0; ix < g.width; ++ix) {
      int a = 0;
      int b = 0;
      int sa = 0;
      int sb = 0;
      const bool has = from_scans.NearestPrimitive(ix, iy, &a, &b);
      ASSERT_EQ(has, from_surfaces.NearestPrimitive(ix, iy, &sa, &sb));
      if (!has) continue;
      ASSERT_EQ(a, sa);
      ASSERT_EQ(b, sb);
      Eigen::Vector2d n = Eigen::Vector2d::Zero();
      Eigen::Vector2d sn = Eigen::Vector2d::Zero();
      const bool has_normal = from_scans.NearestNormal(ix, iy, &n);
      ASSERT_EQ(has_normal, from_surfaces.NearestNormal(ix, iy, &sn));
      ASSERT_EQ(has_normal, from_scans.PrimitiveNormal(a, b, &n));
      ASSERT_EQ(has_normal, from_surfaces.PrimitiveNormal(a, b, &sn));
      with_normal += has_normal ? 1 : 0;
      lone += has_normal ? 0 : 1;
      EXPECT_EQ(n.x(), sn.x());
      EXPECT_EQ(n.y(), sn.y());
      for (const int v : {a, b}) {
        EXPECT_EQ(from_scans.vertex_normal(v).x(), from_surfaces.vertex_normal(v).x());
        EXPECT_EQ(from_scans.vertex_normal(v).y(), from_surfaces.vertex_normal(v).y());
      }
    }
  }
  EXPECT_GT(with_normal, 5000);
  EXPECT_GT(lone, 20);
}

TEST(ReferenceFieldTest, VertexNormalsAreTheLeastScatterDirectionOfTheirNeighbours) {
  // Each vertex's normal (MakeScanSurface) against the smallest eigenvector of the scatter of
  // the vertex and its joined neighbours up to five beams away, from Eigen's iterative solver
  // (the reference): unit, the same direction up to sign to 1e-12, on noisy walls at every
  // heading, on a corner (a wide spread of eigenvalues) and on a square of four points (exact
  // binary coordinates), whose scatter is isotropic (no direction: (1, 0), as the iterative solver
  // gives).
  std::mt19937 rng(7);
  std::normal_distribution<double> noise(0.0, 0.01);
  int checked = 0;
  for (int k = 0; k < 72; ++k) {
    const double heading = k * (M_PI / 36.0) + 0.013;
    const Eigen::Vector2d along(std::cos(heading), std::sin(heading));
    const Eigen::Vector2d across(-along.y(), along.x());
    const Eigen::Vector2d start(3.0 * k - 100.0, 12.5 - 0.4 * k);
    PointCloud scan;
    for (int i = 0; i < 30; ++i) {
      // A bend at i = 15 (a corner) every other wall.
      const double t = 0.04 * i;
      Eigen::Vector2d p = start + t * along;
      if (k % 2 == 1 && i >= 15) p = start + 0.6 * along + (t - 0.6) * across;
      scan.push_back(p + noise(rng) * across);
    }
    const ScanSurface surface = MakeScanSurface(scan, 0.2);
    for (size_t i = 0; i < scan.size(); ++i) {
      const size_t lo = i >= 5 ? i - 5 : 0;
      const size_t hi = std::min(scan.size() - 1, i + 5);
      Eigen::Vector2d mean = Eigen::Vector2d::Zero();
      for (size_t j = lo; j <= hi; ++j) mean += scan[j];
      mean /= static_cast<double>(hi - lo + 1);
      Eigen::Matrix2d scatter = Eigen::Matrix2d::Zero();
      for (size_t j = lo; j <= hi; ++j) scatter += (scan[j] - mean) * (scan[j] - mean).transpose();
      const Eigen::Vector2d expected =
          Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d>(scatter).eigenvectors().col(0);
      const Eigen::Vector2d& n = surface.normals[i];
      ASSERT_NEAR(n.norm(), 1.0, 1e-12) << k << " " << i;
      EXPECT_NEAR(std::abs(n.dot(expected)), 1.0, 1e-12) << k << " " << i;
      ++checked;
    }
  }
  EXPECT_EQ(checked, 72 * 30);
  const ScanSurface square =
      MakeScanSurface({Eigen::Vector2d(1.0, 1.0), Eigen::Vector2d(1.125, 1.0),
                       Eigen::Vector2d(1.125, 1.125), Eigen::Vector2d(1.0, 1.125)},
                      0.2);
  EXPECT_NEAR(std::abs(square.normals[0].x()), 1.0, 1e-12);
  EXPECT_NEAR(square.normals[0].y(), 0.0, 1e-12);
}

TEST(ReferenceFieldTest, LikelihoodBoundsAreThoseOfItsValues) {
  // The bounds the likelihood pass finds (over stored cells only) are the largest value and
  // the exact-sums test of all its values: a pyramid on them equals one that scans level 0.
  // sigma 0.05 (cut at 3 sigma: exact sums) and 0.02 (values below 2^-7: not exact).
  const ReferenceField field(NoisyRoomScans(4), ReferenceFieldOptions{});
  for (const double sigma : {0.05, 0.02}) {
    const LikelihoodGrid grid(field, sigma);
    ASSERT_TRUE(grid.bounds().has_value());
    const GridGeometry& g = grid.geometry();
    std::vector<float> values;
    float most = 0.0f;
    for (int iy = 0; iy < g.height; ++iy) {
      for (int ix = 0; ix < g.width; ++ix) {
        values.push_back(grid.Value(ix, iy));
        most = std::max(most, values.back());
      }
    }
    EXPECT_EQ(grid.bounds()->max_value, most);
    const LikelihoodGrid given(g, values);
    EXPECT_FALSE(given.bounds().has_value());
    const MaxGridPyramid scanned(LikelihoodGrid(given), 3, /*build_levels=*/true);
    const MaxGridPyramid bounded(LikelihoodGrid(grid), 3, /*build_levels=*/true);
    EXPECT_EQ(bounded.max_value(), scanned.max_value());
    EXPECT_EQ(bounded.exact_sums(), scanned.exact_sums());
    EXPECT_EQ(bounded.exact_sums(), sigma == 0.05);
    EXPECT_TRUE(bounded.SameBase(scanned));
    for (int h = 0; h < 3; ++h) {
      const auto a = bounded.level(h);
      const auto b = scanned.level(h);
      ASSERT_EQ(a.width, b.width);
      ASSERT_EQ(a.height, b.height);
      for (int k = 0; k < a.width * a.height; ++k) ASSERT_EQ(a.values[k], b.values[k]);
    }
  }
}

TEST(ReferenceFieldTest, EmptyReference) {
  const ReferenceField field(std::vector<PointCloud>{}, ReferenceFieldOptions{});
  Eigen::Vector2d v;
  EXPECT_EQ(field.num_points(), 0u);
  EXPECT_FALSE(field.NearestVector(0, 0, &v));
  EXPECT_FALSE(field.Interpolate({0.0, 0.0}, &v));
}

}  // namespace
}  // namespace anchormap
