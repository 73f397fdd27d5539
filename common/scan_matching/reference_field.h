#pragma once
// The reference of a match (one keyframe's scan, or a local submap of several scans placed at
// their poses) as a vector field on a grid: for each cell, the vector from the cell's centre to
// the nearest point of the reference surface. The surface is each scan's returns in beam order,
// consecutive returns closer than max_join_gap_m joined by a segment (a wall between two beams
// is a wall, not two dots: a query point between two reference beams is then at distance ~0,
// not half the beam spacing). Vectors are kept within max_distance_m of the surface only.
//
// Near a straight wall the vector field is linear in position, so bilinear interpolation of it
// is exact there: Interpolate gives a point-to-line residual with its Jacobian at any point,
// which the refinement and the covariance use; the likelihood grid uses the cell values.

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "common/scan_matching/grid_geometry.h"
#include "common/scan_matching/point_cloud.h"
#include "common/util/status.h"

namespace anchormap {

struct ReferenceFieldOptions {
  double resolution_m = 0.05;
  // Vectors are stored for cells whose centre is at most this far from the surface.
  double max_distance_m = 0.15;
  // Consecutive returns of one scan at most this far apart are joined by a wall segment.
  double max_join_gap_m = 0.2;
  // Extra cells around the reference's bounding box (a query slightly outside still scores).
  double margin_m = 0.3;

  Status Validate() const;
};

// One scan's surface as a field joins it: which consecutive returns are one wall, each
// return's normal and the normal of the primitive that starts there. A function of the points
// alone: a local map that keeps its scans makes it once per scan, not at every rebuild (the
// normals' eigen-decompositions were a fifth of a build).
struct ScanSurface {
  double max_join_gap_m = 0.0;
  PointCloud points;
  std::vector<uint8_t> joined;                 // joined[i]: points i and i + 1 are one wall
  std::vector<Eigen::Vector2d> normals;        // per point, zero for a lone return
  std::vector<Eigen::Vector2d> start_normals;  // per point, zero where it is a lone return
};
ScanSurface MakeScanSurface(PointCloud points, double max_join_gap_m);

class ReferenceField {
 public:
  // `scans`: each scan's points in the reference frame, in beam order. An empty input gives an
  // empty field (every lookup misses).
  ReferenceField(const std::vector<PointCloud>& scans, const ReferenceFieldOptions& options);
  // The same field from the scans' surfaces (made with options.max_join_gap_m).
  ReferenceField(const std::vector<std::shared_ptr<const ScanSurface>>& surfaces,
                 const ReferenceFieldOptions& options);

  const GridGeometry& geometry() const { return geometry_; }
  const ReferenceFieldOptions& options() const { return options_; }
  size_t num_points() const { return num_points_; }

  // The vector from cell (ix, iy)'s centre to the nearest surface point; false when the cell
  // is outside the grid or farther than max_distance_m from the surface.
  bool NearestVector(int ix, int iy, Eigen::Vector2d* v) const;
  // NearestVector of the cell stored at `index` (GridGeometry::Index), as the floats it keeps.
  bool StoredVector(size_t index, float* x, float* y) const {
    if (std::isnan(vx_[index])) return false;
    *x = vx_[index];
    *y = vy_[index];
    return true;
  }
  // f(index, x, y) for every stored cell (StoredVector true), visiting only the tiles of
  // kTile x kTile cells that some primitive's box reached: the others hold nothing (a one-scan
  // reference's grid spans the scan's range; ~10 % of its tiles lie near a wall at 100 x 180).
  // Tile by tile, not in storage order.
  static constexpr int kTileShift = 3;
  static constexpr int kTile = 1 << kTileShift;
  template <typename F>
  void ForEachStored(F&& f) const;
  // Those tiles: row-major, tiles_width() a row, 1 where a box reached the tile (every stored
  // cell lies in one).
  int tiles_width() const { return tiles_width_; }
  const std::vector<uint8_t>& reached_tiles() const { return reached_tiles_; }
  // Bilinear interpolation of the four cell vectors around p, and optionally its derivative
  // with respect to p; false when any of the four is missing.
  bool Interpolate(const Eigen::Vector2d& p, Eigen::Vector2d* v,
                   Eigen::Matrix2d* dv_dp = nullptr) const;
  // Interpolate, and when it succeeds the cell containing p (GridGeometry::CellOf, from the
  // same quotients computed once): the refinement and the covariance's samples ask both, with
  // NearestNormal, for every point of every pose they try.
  bool InterpolateInCell(const Eigen::Vector2d& p, Eigen::Vector2d* v, Eigen::Vector2i* cell) const;
  // The surface primitive nearest to cell (ix, iy)'s centre: the segment from vertex a to
  // vertex b (a == b for a lone point); false where NearestVector is false.
  bool NearestPrimitive(int ix, int iy, int* a, int* b) const;
  // The reference's points (all scans, in order); primitives index them.
  const Eigen::Vector2d& vertex(int i) const { return vertices_[i]; }
  // The surface normal at a primitive (unit, sign arbitrary): the mean of its vertices'
  // normals, each the least-scatter direction of the vertex and its joined neighbours up to two
  // beams away (a wall's direction smoothed over 4 beam spacings, not the noisy segment's own);
  // false for a lone return. Only for a primitive some cell holds (NearestPrimitive's a, b):
  // a field built from scans makes the normals of those primitives' vertices alone (the
  // others' are zero).
  bool PrimitiveNormal(int a, int b, Eigen::Vector2d* n) const;
  // A vertex's own normal (zero for a lone return); the same restriction.
  const Eigen::Vector2d& vertex_normal(int i) const { return normals_[i]; }
  // NearestPrimitive followed by PrimitiveNormal, the same normal, from a table built with the
  // field: the refinement and the covariance's samples ask it for every point of every pose.
  bool NearestNormal(int ix, int iy, Eigen::Vector2d* n) const;
  // InterpolateInCell followed by NearestNormal for n points at once (x and y apart), the same
  // bits as those calls point by point, four points a step with AVX2 where the CPU has it (the
  // score distribution asks it for every point of 125 poses per match). found[i]: the
  // interpolation succeeded and (vx, vy)[i] is its vector; has_normal[i]: then also the normal
  // (nx, ny)[i]. Other entries are unspecified.
  struct Lookups {
    std::vector<double> qx, qy;          // the points (filled by the caller)
    std::vector<double> vx, vy, nx, ny;  // the answers
    std::vector<uint8_t> found, has_normal;
    void resize(size_t n);
  };
  void InterpolateWithNormals(Lookups* lookups) const;

 private:
  bool InterpolateImpl(const Eigen::Vector2d& p, Eigen::Vector2d* v, Eigen::Matrix2d* dv_dp,
                       Eigen::Vector2i* cell) const;
  void Build(const std::vector<const ScanSurface*>& surfaces);
  // Stores the segment [a, b] (a == b: a lone point) in every cell within max_distance_m where
  // it is nearer than what the cell holds (ties to the later primitive). `centre_x`: the cells'
  // centre x per column; `best_sq`: the squared distance of what each cell holds, max_sq where
  // it holds nothing yet (then best_sq's own value is not read).
  void AddPrimitive(int a, int b, const std::vector<double>& centre_x, float max_sq,
                    float* best_sq);
  // Bit k set where cell index + k holds a vector, k < kTile.
  uint32_t StoredBits(size_t index) const;
  // Marks the tiles of the cell box [x0, x1] x [y0, y1] as reached.
  void MarkTiles(int x0, int y0, int x1, int y1);

  ReferenceFieldOptions options_;
  GridGeometry geometry_;
  size_t num_points_ = 0;
  // NaN where no vector is stored; the only array filled for every cell: vy_ and primitive_a_
  // are written where a vector is stored and read nowhere else (every reader tests vx_ first).
  std::vector<float> vx_;
  std::unique_ptr<float[]> vy_;
  std::unique_ptr<int32_t[]> primitive_a_;  // the nearest primitive: the vertex it starts at
  // Per tile (row-major, tiles_width_ a row): 1 where a primitive's box reached it.
  int tiles_width_ = 0;
  std::vector<uint8_t> reached_tiles_;
  // Per vertex a, the other end b of the one primitive that starts there (a + 1 when joined to
  // the next return, else a): a function of a, so kept per vertex, not per cell.
  std::vector<int32_t> primitive_ends_;
  std::vector<Eigen::Vector2d> vertices_;
  std::vector<Eigen::Vector2d> normals_;  // zero where a vertex has no joined neighbour
  // Per vertex a, PrimitiveNormal(a, b) of the one primitive that starts at a (b = a or a + 1),
  // zero when it has none (a lone return).
  std::vector<Eigen::Vector2d> start_normals_;
};

// Inline: the refinement and the score distribution call these two for every point of every
// pose they try (perf, 100 robots x 60 s: Interpolate 9 % and NearestNormal 2.4 % of the
// replay's samples as out-of-line calls).
inline bool ReferenceField::Interpolate(const Eigen::Vector2d& p, Eigen::Vector2d* v,
                                        Eigen::Matrix2d* dv_dp) const {
  return InterpolateImpl(p, v, dv_dp, nullptr);
}

inline bool ReferenceField::InterpolateInCell(const Eigen::Vector2d& p, Eigen::Vector2d* v,
                                              Eigen::Vector2i* cell) const {
  return InterpolateImpl(p, v, nullptr, cell);
}

inline bool ReferenceField::InterpolateImpl(const Eigen::Vector2d& p, Eigen::Vector2d* v,
                                            Eigen::Matrix2d* dv_dp, Eigen::Vector2i* cell) const {
  // Cell centres are at origin + (i + 0.5) r: the four around p start at floor(u - 0.5).
  const double r = geometry_.resolution;
  const double qx = (p.x() - geometry_.origin.x()) / r;  // CellOf's quotients
  const double qy = (p.y() - geometry_.origin.y()) / r;
  const double ux = qx - 0.5;
  const double uy = qy - 0.5;
  if (!std::isfinite(ux) || !std::isfinite(uy)) return false;
  const double fx = std::floor(ux);
  const double fy = std::floor(uy);
  if (fx < 0.0 || fy < 0.0 || fx + 1.0 >= geometry_.width || fy + 1.0 >= geometry_.height) {
    return false;
  }
  const int ix = static_cast<int>(fx);
  const int iy = static_cast<int>(fy);
  const double tx = ux - fx;
  const double ty = uy - fy;
  // The four cells are inside the grid (checked above): read them without NearestVector's
  // bounds checks (this runs for every point of every pose the refinement and covariance try).
  const int i00 = geometry_.Index(ix, iy);
  const int i01 = i00 + geometry_.width;
  if (std::isnan(vx_[i00]) || std::isnan(vx_[i00 + 1]) || std::isnan(vx_[i01]) ||
      std::isnan(vx_[i01 + 1])) {
    return false;
  }
  const Eigen::Vector2d v00(vx_[i00], vy_[i00]);
  const Eigen::Vector2d v10(vx_[i00 + 1], vy_[i00 + 1]);
  const Eigen::Vector2d v01(vx_[i01], vy_[i01]);
  const Eigen::Vector2d v11(vx_[i01 + 1], vy_[i01 + 1]);
  *v = (1 - tx) * (1 - ty) * v00 + tx * (1 - ty) * v10 + (1 - tx) * ty * v01 + tx * ty * v11;
  if (dv_dp != nullptr) {
    dv_dp->col(0) = ((1 - ty) * (v10 - v00) + ty * (v11 - v01)) / r;
    dv_dp->col(1) = ((1 - tx) * (v01 - v00) + tx * (v11 - v10)) / r;
  }
  // p lies within the grid's cells here: the casts cannot overflow.
  if (cell != nullptr) *cell = {static_cast<int>(std::floor(qx)), static_cast<int>(std::floor(qy))};
  return true;
}

inline bool ReferenceField::NearestNormal(int ix, int iy, Eigen::Vector2d* n) const {
  if (!geometry_.Contains(ix, iy)) return false;
  const int index = geometry_.Index(ix, iy);
  if (std::isnan(vx_[index])) return false;  // no primitive stored (primitive_a_ unset)
  const int a = primitive_a_[index];
  const Eigen::Vector2d& normal = start_normals_[a];
  if (normal.x() == 0.0 && normal.y() == 0.0) return false;  // a unit normal is never zero
  *n = normal;
  return true;
}

template <typename F>
void ReferenceField::ForEachStored(F&& f) const {
  const int width = geometry_.width;
  const int height = geometry_.height;
  const int tiles_height =
      tiles_width_ == 0 ? 0 : static_cast<int>(reached_tiles_.size()) / tiles_width_;
  for (int ty = 0; ty < tiles_height; ++ty) {
    const int y_end = std::min((ty + 1) << kTileShift, height);
    for (int tx = 0; tx < tiles_width_; ++tx) {
      if (!reached_tiles_[static_cast<size_t>(ty) * tiles_width_ + tx]) continue;
      const int x0 = tx << kTileShift;
      const int x_end = std::min(x0 + kTile, width);
      for (int iy = ty << kTileShift; iy < y_end; ++iy) {
        const size_t row = static_cast<size_t>(iy) * width;
        if (x_end - x0 == kTile) {  // a whole run: its stored cells as bits
          for (uint32_t bits = StoredBits(row + x0); bits != 0; bits &= bits - 1) {
            const size_t i = row + x0 + static_cast<size_t>(__builtin_ctz(bits));
            f(i, vx_[i], vy_[i]);
          }
          continue;
        }
        for (size_t i = row + x0; i < row + x_end; ++i) {
          if (!std::isnan(vx_[i])) f(i, vx_[i], vy_[i]);
        }
      }
    }
  }
}

// Closest point to p on the segment [a, b] (a == b allowed).
Eigen::Vector2d ClosestPointOnSegment(const Eigen::Vector2d& p, const Eigen::Vector2d& a,
                                      const Eigen::Vector2d& b);

}  // namespace anchormap
