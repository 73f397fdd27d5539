#pragma once
// Fill-reducing variable ordering for a batch step: CCOLAMD (SuiteSparse) on the block
// structure, one column per variable (pose or anchor), one row per factor. Variables
// flagged `keep_last` (each trajectory's latest pose and every anchor) are constrained
// to the end, so new measurements touch only the bottom right of R and anchor
// covariances come from R's last blocks (docs/METHOD.md section 5).

#include <vector>

namespace anchormap {

// factor_variables[f] lists the variables (0..num_variables-1) factor f touches.
// Returns order[k] = the variable placed at elimination position k.
std::vector<int> ComputeOrdering(int num_variables,
                                 const std::vector<std::vector<int>>& factor_variables,
                                 const std::vector<bool>& keep_last);

}  // namespace anchormap
