#pragma once
// The global search for an unknown relative pose (a first encounter of two robots, a loop
// closure with no usable prior): the correlative matcher's lattice over every heading and every
// translation that puts the query's origin inside the reference's grid, solved exactly by
// branch and bound over the max-grid pyramid (the idea of Hess et al., ICRA 2016), then the
// same refinement, covariance and overlap as MatchLocal. The cost grows with the reference's
// area times the number of headings (2 pi / AngleStepForRange), but whole blocks of 2^(levels-1)
// cells are pruned at once.

#include <optional>
#include <string>

#include "common/scan_matching/correlative_matcher.h"
#include "common/util/status.h"

namespace anchormap {

struct GlobalSearchOptions {
  // A wrong global match costs more than a missed one: a higher bar than the local default.
  MatchOptions match{0.5, 0.03, 0.1, true};

  Status Validate() const { return match.Validate(); }
};

// T_reference_query for `query` (points in its body frame), or nullopt when no pose scores
// above min_score. Options must be valid.
std::optional<MatchResult> GlobalSearch(const ScanReference& reference, const PointCloud& query,
                                        const GlobalSearchOptions& options);

// The window GlobalSearch uses (exposed for tests and the benchmark).
SearchWindow GlobalSearchWindow(const ScanReference& reference, const PointCloud& query);

}  // namespace anchormap
