#pragma once
// Fill-reducing variable ordering for a batch step: CCOLAMD (SuiteSparse) on the block
// structure, one column per variable (pose or anchor), one row per factor. Variables
// flagged `keep_last` (every anchor, and each trajectory's latest pose with
// SmootherOptions::latest_poses_last) are constrained to the end, so anchor covariances
// come from R's last blocks (docs/METHOD.md section 5) and new measurements on them touch
// only the bottom right of R.

#include <vector>

#include "common/util/status.h"

namespace anchormap {

// factor_variables[f] lists the variables (0..num_variables-1) factor f touches; all
// three vectors must agree in size (a bug otherwise). Returns order[k] = the variable
// placed at elimination position k, or kNumericalFailure when CCOLAMD fails.
Result<std::vector<int>> ComputeOrdering(int num_variables,
                                         const std::vector<std::vector<int>>& factor_variables,
                                         const std::vector<bool>& keep_last);

// The same with the factors' variables in one flat list: factor f touches
// variables[factor_start[f] .. factor_start[f+1]) (factor_start has one entry more than
// there are factors). Saves a vector per factor where orderings run often (partial steps).
Result<std::vector<int>> ComputeOrdering(int num_variables, const std::vector<int>& factor_start,
                                         const std::vector<int>& variables,
                                         const std::vector<bool>& keep_last);

// Test seam: the next `count` calls of ComputeOrdering fail as if CCOLAMD had, so that
// tests can check what a failed batch step leaves behind. Not for production code.
void FailNextOrderingsForTesting(int count);

}  // namespace anchormap
