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
      likelihood_(field_, options.likelihood_sigma_m),
      pyramid_(likelihood_, options.num_levels) {}

ScanReference::ScanReference(const std::vector<std::shared_ptr<const ScanSurface>>& surfaces,
                             const ScanReferenceOptions& options)
    : options_(options),
      field_(surfaces, FieldOptions(options)),
      likelihood_(field_, options.likelihood_sigma_m),
      pyramid_(likelihood_, options.num_levels) {}

const ByteMaxGrids* ScanReference::byte_bounds() const {
  if (!pyramid_.exact_sums()) return nullptr;
  std::call_once(bytes_->once,
                 [this] { bytes_->grids = std::make_unique<ByteMaxGrids>(pyramid_); });
  return bytes_->grids.get();
}

}  // namespace anchormap
