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
// The diagonal blocks are kept inverted (R_pp^-1, upper triangular): a row's 3x3 solve is
// then a product, not a chain of three dependent divisions, which on a sparse R (M3500:
// 23 blocks per row) was the solves' critical path. The off-diagonal blocks are kept as
// floats: the solves stream all of R and are memory-bound on a large one, and R only
// preconditions the correction (both solves use the same rounded R, and J^T J is applied
// exactly). The results differ from SparseR's solves by that rounding.

#include <array>
#include <cstdint>
#include <vector>

#include <Eigen/Core>

#include "common/solver/sparse_r.h"

namespace anchormap {

class FlatR {
 public:
  // Brings the copy up to date with `r`; returns the block rows copied.
  int Refresh(const SparseR& r);
  // An off-diagonal block as the solves see it (rounded to float).
  static Eigen::Matrix3d Rounded(const Eigen::Matrix3d& block);

  int size() const { return static_cast<int>(row_start_.size()) - 1; }
  // v <- R^-T v by block forward substitution; returns |R^-T v|^2.
  double SolveTransposedInPlace(std::vector<Eigen::Vector3d>* v) const;
  // v <- R^-1 v by block back-substitution.
  void SolveInPlace(std::vector<Eigen::Vector3d>* v) const;

 private:
  uint64_t source_id_ = 0;  // SparseR::instance_id() copied from; 0: none
  uint64_t source_revision_ = 0;
  // By block row: R_pp^-1's upper triangle (00, 01, 02, 11, 12, 22).
  std::vector<std::array<double, 6>> inverse_diagonals_;
  std::vector<int64_t> row_start_{0};  // by block row, and one past the last
  std::vector<int> columns_;           // off-diagonal blocks' columns, in row order
  // The blocks themselves, same order, 9 floats each in the order the solves read them
  // (pairs of entries side by side: flat_r.cc's StoreBlock).
  std::vector<float> blocks_;
  std::vector<int64_t> old_start_;  // work space of Refresh: row_start_ before it, from `from`
};

}  // namespace anchormap
