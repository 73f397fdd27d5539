#pragma once
// The cells of a square-celled 2D grid: cell (ix, iy) covers
// [origin + ix * resolution, origin + (ix + 1) * resolution) on each axis; its centre is at
// origin + (ix + 0.5) * resolution.

#include <cmath>

#include <Eigen/Core>

namespace anchormap {

struct GridGeometry {
  Eigen::Vector2d origin{0.0, 0.0};  // lower-left corner of cell (0, 0)
  double resolution = 0.05;
  int width = 0;   // cells along x
  int height = 0;  // cells along y

  bool Contains(int ix, int iy) const { return ix >= 0 && iy >= 0 && ix < width && iy < height; }
  int Index(int ix, int iy) const { return iy * width + ix; }
  size_t num_cells() const { return static_cast<size_t>(width) * static_cast<size_t>(height); }
  Eigen::Vector2d CellCentre(int ix, int iy) const {
    return origin + resolution * Eigen::Vector2d(ix + 0.5, iy + 0.5);
  }
  // The cell containing p (it may lie outside the grid).
  Eigen::Vector2i CellOf(const Eigen::Vector2d& p) const {
    return {static_cast<int>(std::floor((p.x() - origin.x()) / resolution)),
            static_cast<int>(std::floor((p.y() - origin.y()) / resolution))};
  }
  Eigen::Vector2d max_corner() const {
    return origin + resolution * Eigen::Vector2d(width, height);
  }
};

}  // namespace anchormap
