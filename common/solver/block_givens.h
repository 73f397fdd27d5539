#pragma once
// The inner kernel of SparseR::Eliminate: folds three new rows into one block row of R.
//
// The work space holds 6 rows of `width` columns (row-major, `stride` apart): rows 0-2
// are R's block row (columns 0-2 its upper-triangular diagonal block), rows 3-5 the new
// rows. Nine Givens rotations zero rows 3-5 in columns 0-2; they are all computed on the
// leading 6x3 block first and then applied to the remaining columns in one pass, so each
// column is loaded and stored once instead of nine times. On x86-64 the kernel is
// compiled twice (AVX2 + FMA, and baseline) and the loader picks the one the CPU runs.

namespace anchormap {

void EliminateBlockRow(double* work, int stride, int width);

}  // namespace anchormap
