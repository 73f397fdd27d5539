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
  // The lattice search (every heading, the whole grid: its cost is points x poses) scores only
  // the query's points at least this far from the last one kept, in scan order: near the robot
  // a wall's returns lie a few cm apart and tell the same as a few of them. Refinement,
  // overlap and covariance use every point. 0: every point.
  double query_spacing_m = 0.1;

  Status Validate() const;
};

// T_reference_query for `query` (points in its body frame), or nullopt when no pose scores
// above min_score. Options must be valid.
std::optional<MatchResult> GlobalSearch(const ScanReference& reference, const PointCloud& query,
                                        const GlobalSearchOptions& options);

// The points of `query` at least `spacing_m` from the last one kept, in order (the first kept).
PointCloud ThinOutQuery(const PointCloud& query, double spacing_m);

// The window GlobalSearch uses (exposed for tests and the benchmark).
SearchWindow GlobalSearchWindow(const ScanReference& reference, const PointCloud& query);

}  // namespace anchormap
