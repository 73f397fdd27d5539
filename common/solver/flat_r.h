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
//
// The blocks are kept row-major: the forward solve takes a block's three rows as three
// 4-lane vectors, the back solve its three columns (permuted out of the rows: one copy of
// R serves both, so the back solve finds the end of R that the forward solve just read
// still in the cache). Both work in registers of four doubles (AVX2 where the CPU has it)
// with the plain scalar code's operations per entry, in its order: the same bits
// (flat_r_test.cc compares them with a scalar reference).

#include <array>
#include <atomic>
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
  // y <- R^-T v (y resized to v's size; v may be y), without a copy of v first; returns
  // |R^-T v|^2.
  double SolveTransposed(const std::vector<Eigen::Vector3d>& v,
                         std::vector<Eigen::Vector3d>* y) const;
  // v <- R^-1 v by block back-substitution.
  void SolveInPlace(std::vector<Eigen::Vector3d>* v) const;
  // Tests turn the AVX2 solves off to run their portable twins (the same bits).
  static std::atomic<bool>& VectorSolvesAllowed();

 private:
  uint64_t source_id_ = 0;  // SparseR::instance_id() copied from; 0: none
  uint64_t source_revision_ = 0;
  // By block row: R_pp^-1's upper triangle (00, 01, 02, 11, 12, 22).
  std::vector<std::array<double, 6>> inverse_diagonals_;
  std::vector<int64_t> row_start_{0};  // by block row, and one past the last
  std::vector<int> columns_;           // off-diagonal blocks' columns, in row order
  // The blocks themselves, same order, 9 floats each, row-major; then 3 zeros, read by the
  // last block's last 4-float load.
  std::vector<float> row_major_;
  std::vector<int64_t> old_start_;  // work space of Refresh: row_start_ before it, from `from`
  // Work space of the forward solve: the vector with 4 doubles per entry (the 4th zero), so
  // that each x_q is read and written as one aligned 32-byte vector. The solves are const
  // for their callers; FlatR is the smoother's own (one thread).
  struct alignas(32) Padded {
    double x[4];
  };
  mutable std::vector<Padded> padded_;
};

}  // namespace anchormap
