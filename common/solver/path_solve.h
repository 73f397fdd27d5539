#pragma once
// |R^-T g|^2 for a g that is non-zero at few positions (the smoother's skip test: what the
// new factors' gradient J^T e adds to the decrease a correction would predict). The
// forward substitution R^T y = g reaches only the block rows on those positions' paths up
// the elimination tree, the rows their Givens updates touched, so this costs those rows
// instead of all of R. Solved on SparseR itself: FlatR's copy is refreshed only when a
// correction runs.

#include <limits>
#include <utility>
#include <vector>

#include <Eigen/Core>

#include "common/solver/sparse_r.h"

namespace anchormap {

class PathSolve {
 public:
  // g as (position, value) pairs (a position may repeat: the values add up). Rows are
  // solved in ascending order and |y|^2 only grows: once it passes `stop_above` the
  // partial sum is returned (above it) and the rest is not solved.
  double SquaredNorm(const SparseR& r, const std::vector<std::pair<int, Eigen::Vector3d>>& g,
                     double stop_above = std::numeric_limits<double>::infinity());
  // Block rows the last call solved.
  int rows_solved() const { return rows_solved_; }

 private:
  // Work space, zero (and unqueued) between calls.
  std::vector<Eigen::Vector3d> value_;
  std::vector<char> queued_;
  std::vector<int> heap_;  // queued rows, a min-heap
  int rows_solved_ = 0;
};

}  // namespace anchormap
