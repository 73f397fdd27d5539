#include "common/scan_matching/likelihood_grid.h"

#include <algorithm>
#include <cassert>
#include <cmath>
#include <stdexcept>
#include <utility>

namespace anchormap {

LikelihoodGrid::LikelihoodGrid(const ReferenceField& field, double sigma_m)
    : geometry_(field.geometry()), values_(geometry_.num_cells(), 0.0f) {
  if (!(sigma_m > 0.0)) throw std::invalid_argument("LikelihoodGrid: sigma_m must be > 0");
  const double k = -0.5 / (sigma_m * sigma_m);
  // Only the cells holding a vector (the field visits the tiles a wall reached). The largest
  // value and the exact-sums test come with them: the other cells are 0, which passes the test
  // and does not raise the maximum (std::max of floats that are not NaN: any order).
  constexpr float kExactFloor = 1.0f / 128.0f;  // MaxGridPyramid::exact_sums's 2^-7
  ValueBounds bounds;
  float* values = values_.data();
  field.ForEachStored([&](size_t i, float x, float y) {
    const double dx = x;
    const double dy = y;
    const float value = static_cast<float>(std::exp(k * (dx * dx + dy * dy)));
    values[i] = value;
    bounds.max_value = std::max(bounds.max_value, value);
    bounds.exact_sums =
        bounds.exact_sums && (value == 0.0f || (value >= kExactFloor && value <= 1.0f));
  });
  bounds_ = bounds;
}

LikelihoodGrid::LikelihoodGrid(const GridGeometry& geometry, std::vector<float> values)
    : geometry_(geometry), values_(std::move(values)) {
  if (values_.size() != geometry_.num_cells()) {
    throw std::invalid_argument("LikelihoodGrid: values must have width x height entries");
  }
}

}  // namespace anchormap
