#include "common/scan_matching/scan_reference.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace anchormap {

std::optional<std::string> ScanReferenceOptions::Validate() const {
  if (!(resolution_m > 0.0) || !std::isfinite(resolution_m)) return "resolution_m must be > 0";
  if (!(likelihood_sigma_m > 0.0) || !std::isfinite(likelihood_sigma_m)) {
    return "likelihood_sigma_m must be > 0";
  }
  if (!(max_join_gap_m >= 0.0) || !std::isfinite(max_join_gap_m)) {
    return "max_join_gap_m must be >= 0";
  }
  if (num_levels < 1 || num_levels > 12) return "num_levels must be in [1, 12]";
  return std::nullopt;
}

ReferenceFieldOptions ScanReference::FieldOptions(const ScanReferenceOptions& options) {
  if (const auto error = options.Validate()) {
    throw std::invalid_argument("ScanReference: " + *error);
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

}  // namespace anchormap
