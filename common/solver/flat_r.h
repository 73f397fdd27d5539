#pragma once
// A contiguous copy of R's blocks for the correction's triangular solves (smoother
// correction, docs/ARCHITECTURE.md). SparseR keeps each block row's off-diagonal blocks in
// their own heap vector, which Givens updates grow in place; a solve that streams all of
// R then jumps between scattered allocations (16 MB on city10000, two solves per
// conjugate-gradient iteration). Here the diagonal blocks, the column indices and the
// off-diagonal blocks are three arrays in row order, and a refresh copies only the rows
// from the first one that changed since the last refresh (Givens updates change the rows
// from a new measurement's oldest variable on, mostly recent ones at the end).
//
// The solves do the same floating-point operations in the same order as the ones on
// SparseR's rows: the results are identical.

#include <cstdint>
#include <vector>

#include <Eigen/Core>

#include "common/solver/sparse_r.h"

namespace anchormap {

class FlatR {
 public:
  // Brings the copy up to date with `r`; returns the block rows copied.
  int Refresh(const SparseR& r);

  int size() const { return static_cast<int>(diagonals_.size()); }
  // v <- R^-T v by block forward substitution; returns |R^-T v|^2.
  double SolveTransposedInPlace(std::vector<Eigen::Vector3d>* v) const;
  // v <- R^-1 v by block back-substitution.
  void SolveInPlace(std::vector<Eigen::Vector3d>* v) const;

 private:
  uint64_t source_id_ = 0;  // SparseR::instance_id() copied from; 0: none
  uint64_t source_revision_ = 0;
  std::vector<Eigen::Matrix3d> diagonals_;  // by block row
  std::vector<int64_t> row_start_;          // by block row, and one past the last
  std::vector<int> columns_;                // off-diagonal blocks' columns, in row order
  std::vector<Eigen::Matrix3d> blocks_;     // the blocks themselves, same order
};

}  // namespace anchormap
