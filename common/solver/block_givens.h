#pragma once
// The inner kernel of SparseR::Eliminate: folds three new rows into one block row of R.
//
// `upper` holds R's block row: 3 rows of `width` columns, `stride` apart (columns 0-2 its
// upper-triangular diagonal block); `lower` the three new rows, same layout. Nine Givens
// rotations zero the new rows in columns 0-2; they are all computed on the
// leading 6x3 block first and then applied to the remaining columns in one pass, so each
// column is loaded and stored once instead of nine times. On x86-64 the kernel is
// compiled twice (AVX2 + FMA, and baseline) and the loader picks the one the CPU runs.

#include <atomic>

namespace anchormap {

void EliminateBlockRow(double* upper, double* lower, int stride, int width);

// Tests turn the AVX-512 rotations off to compare them with the AVX2 + FMA build's (x86-64
// with GCC only; elsewhere there is no AVX-512 path).
std::atomic<bool>& BlockGivensAvx512Allowed();

}  // namespace anchormap
