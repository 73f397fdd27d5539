#pragma once
// The reference rasterised as a likelihood grid (Olson, "Real-time correlative scan matching",
// ICRA 2009): each cell holds exp(-d^2 / (2 sigma^2)), d the distance from the cell's centre to
// the nearest reference surface (ReferenceField), 0 beyond the field's max_distance_m. A query
// point that lands in a cell scores its value; the score of a pose is the mean over the
// query's points, in [0, 1]. sigma is the blur: the sensor noise plus the search's
// discretisation, so that a pose one cell off still scores (the search is on a lattice).

#include <optional>
#include <utility>
#include <vector>

#include "common/scan_matching/grid_geometry.h"
#include "common/scan_matching/reference_field.h"

namespace anchormap {

class LikelihoodGrid {
 public:
  // What MaxGridPyramid learns of its level 0 in a pass of its own (the largest value, and
  // whether every value is 0 or in [2^-7, 1]), known here when the grid's own pass found it
  // (a grid built from a field); none for a grid of given values.
  struct ValueBounds {
    float max_value = 0.0f;
    bool exact_sums = true;
  };
  // Precondition: sigma_m > 0.
  LikelihoodGrid(const ReferenceField& field, double sigma_m);
  // A grid of given values (row-major, width x height), for tests of the search.
  LikelihoodGrid(const GridGeometry& geometry, std::vector<float> values);

  const GridGeometry& geometry() const { return geometry_; }
  const std::optional<ValueBounds>& bounds() const { return bounds_; }
  // The values, row-major (the grid is left empty): MaxGridPyramid keeps them as its level 0.
  std::vector<float> TakeValues() && { return std::move(values_); }
  // The cell's value; 0 outside the grid.
  float Value(int ix, int iy) const {
    return geometry_.Contains(ix, iy) ? values_[geometry_.Index(ix, iy)] : 0.0f;
  }
  // The same cells (extent and origin) holding the same values, exactly: a reference built
  // again from the same drawing equals the first.
  bool SameCells(const LikelihoodGrid& other) const {
    return geometry_.width == other.geometry_.width && geometry_.height == other.geometry_.height &&
           geometry_.origin == other.geometry_.origin && values_ == other.values_;
  }

 private:
  GridGeometry geometry_;
  std::vector<float> values_;
  std::optional<ValueBounds> bounds_;
};

}  // namespace anchormap
