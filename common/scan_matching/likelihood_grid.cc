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
  for (int iy = 0; iy < geometry_.height; ++iy) {
    for (int ix = 0; ix < geometry_.width; ++ix) {
      Eigen::Vector2d v;
      if (field.NearestVector(ix, iy, &v)) {
        values_[geometry_.Index(ix, iy)] = static_cast<float>(std::exp(k * v.squaredNorm()));
      }
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
