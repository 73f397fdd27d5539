#include "common/scan_matching/scan_reference.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace anchormap {

Status ScanReferenceOptions::Validate() const {
  if (!(resolution_m > 0.0) || !std::isfinite(resolution_m))
    return Status::Error("resolution_m must be > 0");
  if (!(likelihood_sigma_m > 0.0) || !std::isfinite(likelihood_sigma_m)) {
    return Status::Error("likelihood_sigma_m must be > 0");
  }
  if (!(max_join_gap_m >= 0.0) || !std::isfinite(max_join_gap_m)) {
    return Status::Error("max_join_gap_m must be >= 0");
  }
  if (num_levels < 1 || num_levels > 12) return Status::Error("num_levels must be in [1, 12]");
  return Status::Ok();
}

ReferenceFieldOptions ScanReference::FieldOptions(const ScanReferenceOptions& options) {
  if (const Status valid = options.Validate(); !valid.ok()) {
    throw std::invalid_argument("ScanReference: " + valid.message());
  }
  ReferenceFieldOptions field;
  field.resolution_m = options.resolution_m;
  // Beyond 3 sigma the likelihood is below 1.2 %: stored as 0.
  field.max_distance_m = std::max(3.0 * options.likelihood_sigma_m, 2.0 * options.resolution_m);
  field.max_join_gap_m = options.max_join_gap_m;
  field.margin_m = 0.3;
  return field;
}

ScanReference::ScanReference(const std::vector<PointCloud>& scans,
                             const ScanReferenceOptions& options)
    : options_(options),
      field_(scans, FieldOptions(options)),
      pyramid_(LikelihoodGrid(field_, options.likelihood_sigma_m), options.num_levels,
               /*build_levels=*/false) {}

ScanReference::ScanReference(const std::vector<std::shared_ptr<const ScanSurface>>& surfaces,
                             const ScanReferenceOptions& options)
    : options_(options),
      field_(surfaces, FieldOptions(options)),
      pyramid_(LikelihoodGrid(field_, options.likelihood_sigma_m), options.num_levels,
               /*build_levels=*/false) {}

const MaxGridPyramid& ScanReference::pyramid() const {
  std::call_once(lazy_->levels, [this] {
    // The only change to the pyramid after construction: once, before any reader of its levels.
    pyramid_.BuildLevels();
  });
  return pyramid_;
}

const ByteMaxGrids* ScanReference::byte_bounds() const {
  if (!pyramid_.exact_sums()) return nullptr;
  std::call_once(lazy_->bytes, [this] {
    // The likelihood is 0 outside the field's reached tiles (LikelihoodGrid stores only the
    // cells holding a vector): level 0 is rounded up on those tiles alone.
    const ByteMaxGrids::NonzeroTiles nonzero{ReferenceField::kTileShift, field_.tiles_width(),
                                             field_.reached_tiles().data()};
    lazy_->grids = field_.reached_tiles().empty()
                       ? std::make_unique<ByteMaxGrids>(pyramid_)
                       : std::make_unique<ByteMaxGrids>(pyramid_, nonzero);
  });
  return lazy_->grids.get();
}

}  // namespace anchormap
