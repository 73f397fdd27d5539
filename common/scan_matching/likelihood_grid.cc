#include "common/scan_matching/likelihood_grid.h"

#include <cassert>
#include <cmath>
#include <stdexcept>
#include <utility>

namespace anchormap {

LikelihoodGrid::LikelihoodGrid(const ReferenceField& field, double sigma_m)
    : geometry_(field.geometry()), values_(geometry_.num_cells(), 0.0f) {
  if (!(sigma_m > 0.0)) throw std::invalid_argument("LikelihoodGrid: sigma_m must be > 0");
  const double k = -0.5 / (sigma_m * sigma_m);
  // Cell by cell in storage order (NearestVector's bounds check and index per cell were most
  // of this pass: only a few cells lie near a wall).
  const size_t cells = geometry_.num_cells();
  for (size_t i = 0; i < cells; ++i) {
    float x = 0.0f;
    float y = 0.0f;
    if (field.StoredVector(i, &x, &y)) {
      const double dx = x;
      const double dy = y;
      values_[i] = static_cast<float>(std::exp(k * (dx * dx + dy * dy)));
    }
  }
}

LikelihoodGrid::LikelihoodGrid(const GridGeometry& geometry, std::vector<float> values)
    : geometry_(geometry), values_(std::move(values)) {
  if (values_.size() != geometry_.num_cells()) {
    throw std::invalid_argument("LikelihoodGrid: values must have width x height entries");
  }
}

}  // namespace anchormap
