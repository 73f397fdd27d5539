#pragma once
// The square-root information matrix R (upper triangular) and right-hand side d of the
// linearised system, stored in 3x3 blocks: block row/column p is the variable at
// elimination position p. docs/METHOD.md section 5.
//
// Rows are added by Givens rotations (each zeroing one entry below the diagonal); new
// variables append empty block rows/columns at the end. R^T R = A^T A and R delta = d
// is the least-squares solution of A delta = b.

#include <atomic>
#include <cstdint>
#include <utility>
#include <vector>

#include <Eigen/Core>

namespace anchormap {

// One block row of R: the upper-triangular diagonal block, the blocks to its right
// (sorted by column), and the row's part of d.
struct RBlockRow {
  Eigen::Matrix3d diagonal = Eigen::Matrix3d::Zero();
  std::vector<std::pair<int, Eigen::Matrix3d>> right;  // (column > row, block), sorted
  Eigen::Vector3d rhs = Eigen::Vector3d::Zero();
};

// Three new whitened measurement rows: blocks by column (any order) and rhs.
struct NewRows {
  std::vector<std::pair<int, Eigen::Matrix3d>> blocks;
  Eigen::Vector3d rhs = Eigen::Vector3d::Zero();
};

class SparseR {
 public:
  // The matrix and its bookkeeping as plain values (SmootherState): the order of each
  // column's referencing rows is kept, as partial steps sum over them in that order.
  struct State {
    std::vector<RBlockRow> rows;
    std::vector<std::vector<int>> column_rows;
    int64_t nonzeros = 0;
    int64_t eliminated_block_rows = 0;
    int64_t eliminated_block_columns = 0;
  };
  State ExportState() const {
    return {rows_, column_rows_, nonzeros_, eliminated_block_rows_, eliminated_block_columns_};
  }
  // False (nothing changed) when the column lists do not fit the rows.
  bool ImportState(State state);

  // Tests turn the AVX-512 copies between R's rows and the elimination's work panel off, to
  // compare them with the portable ones (moves: the same bits).
  static std::atomic<bool>& VectorCopiesAllowed();
  int size() const { return static_cast<int>(rows_.size()); }
  // Appends `count` empty block rows/columns at the end (new variables).
  void Append(int count);
  // Removes the block rows from `n` on; they must be empty and unreferenced (appended for an
  // update that did not take place).
  void Truncate(int n);
  // Replaces the whole matrix (after a batch factorisation).
  void Assign(std::vector<RBlockRow> rows);

  // Eliminates three new rows into R by Givens rotations. Block rows that change are
  // appended to `touched` (may repeat). Returns |leftover rhs|^2, the part of the new
  // rows' residual that no variable can absorb. Cost: proportional to the fill of the
  // rows met on the way (only the right part of R changes for recent variables).
  double Eliminate(NewRows rows, std::vector<int>* touched);
  // The same for several measurements at once (one update's): where their paths up R
  // meet, each block row of R is read and written once for all of them instead of once
  // per measurement. Returns the summed leftover.
  double Eliminate(std::vector<NewRows> rows, std::vector<int>* touched);

  // The same with budgets: if the rows would add more than `max_fill` scalar non-zeros to
  // R, or take more than `max_work` of the rotations' work (eliminated_work()), R is left
  // exactly as it was and false is returned (the walk stops at the row where a budget is
  // passed, before its arithmetic); else true and the leftover in `leftover`. A Givens
  // update that fills R past its last ordering's size, or that carries many rows through
  // R's wide rows near the root, is dearer than the batch step that would reorder it.
  bool EliminateWithin(std::vector<NewRows> rows, int64_t max_fill, int64_t max_work,
                       std::vector<int>* touched, double* leftover);

  // The work (eliminated_work()) Eliminate would take for `rows`, from the patterns alone
  // (no arithmetic; exact zeros aside, which only drop blocks, it is Eliminate's); the walk
  // stops once it passes `max_work`.
  int64_t PredictedWork(const std::vector<NewRows>& rows, int64_t max_work) const;

  // Partial re-elimination: replaces the block rows from `p0` on. `new_position[q - p0]`
  // is the new position of old position q >= p0. The old rows `kept` (ascending) stay
  // valid and move to positions p0, p0 + 1, ... with their columns renumbered; `rows`
  // (columns already final) follow them, so kept.size() + rows.size() == size() - p0.
  // Rows before p0 keep their place and get their columns renumbered. `rhs` first sets
  // the right-hand side of the listed rows (by old position).
  void ReplaceTail(int p0, const std::vector<int>& new_position, const std::vector<int>& kept,
                   std::vector<RBlockRow> rows,
                   const std::vector<std::pair<int, Eigen::Vector3d>>& rhs);

  // delta = R^-1 d by full back-substitution.
  void BackSubstitute(std::vector<Eigen::Vector3d>* delta) const;
  // The same for the block rows from `from` to the end only (they reference no row before
  // it); entries of `x` before `from` are neither read nor written.
  void BackSubstituteTail(int from, std::vector<Eigen::Vector3d>* x) const;
  // Recomputes only block rows in `dirty` and, transitively, rows whose inputs changed by
  // more than `threshold` (max-abs); others keep their value. Returns rows recomputed.
  int BackSubstitutePartial(const std::vector<int>& dirty, double threshold,
                            std::vector<Eigen::Vector3d>* delta);

  const RBlockRow& row(int p) const { return rows_[p]; }
  // Block rows that have a block in column q (q excluded), for propagation and covariances.
  const std::vector<int>& RowsReferencing(int q) const { return column_rows_[q]; }

  // Work counters: block rows met by Eliminate, and the block columns they spanned.
  int64_t eliminated_block_rows() const { return eliminated_block_rows_; }
  int64_t eliminated_block_columns() const { return eliminated_block_columns_; }
  // The rotations' work: at every block row met, the carried triples times the blocks of
  // the row's union (diagonal included), summed.
  int64_t eliminated_work() const { return eliminated_work_; }

  // Scalar non-zeros of R (6 per diagonal block, 9 per off-diagonal block).
  int64_t NonZeros() const { return nonzeros_; }
  // Smallest |diagonal entry| of R: near zero means an unconstrained variable.
  double MinAbsDiagonal() const;

  // Change tracking for copies of R (FlatR): every mutating call draws a new revision
  // and stamps the block rows it changed with it. The id is unique per object (a copy
  // gets a new one), so a copy knows whether it was taken from this object.
  uint64_t instance_id() const { return instance_id_.value; }
  uint64_t revision() const { return revision_; }
  // The revision of block row p's last change.
  uint64_t row_revision(int p) const { return row_revision_[p]; }
  // The first block row changed after `revision` (size() if none).
  int FirstRowChangedAfter(uint64_t revision) const;

 private:
  // A process-wide unique id, renewed by copies and moves.
  struct InstanceId {
    InstanceId() : value(Next()) {}
    InstanceId(const InstanceId&) : value(Next()) {}
    InstanceId& operator=(const InstanceId&) {
      value = Next();
      return *this;
    }
    static uint64_t Next();
    uint64_t value;
  };
  // Starts a mutating call: a new revision for its stamps.
  void BeginChange() { ++revision_; }
  void Stamp(int p) { row_revision_[p] = revision_; }
  void StampAll() { row_revision_.assign(rows_.size(), revision_); }

  Eigen::Vector3d SolveRow(int p, const std::vector<Eigen::Vector3d>& delta) const;
  // False when `rows` cannot take more than `max_work` (a bound without the walk: every
  // triple at every row, over at most the blocks R and the fill budget allow).
  bool WorkCouldPass(const std::vector<NewRows>& rows, int64_t max_fill, int64_t max_work) const;

  std::vector<RBlockRow> rows_;
  std::vector<std::vector<int>> column_rows_;
  // New rows on their way up R: 3 * triples rows of `panel` from `first_row` (row-major,
  // capacity kept between calls), over `columns` (sorted): column j's 3 scalar columns
  // start at at[j], the rhs at rhs_at. A carry that leaves a block row keeps the work
  // panel it was rotated in (swapped, not copied), so its columns are where that row's
  // union put them.
  using Panel = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;
  struct Carry {
    std::vector<int> columns;
    std::vector<int> at;
    std::vector<int> in_union;  // work space: union index of each column
    Panel panel;
    int first_row = 0;
    int rhs_at = 0;
    int triples = 0;
    bool alive = false;
  };
  // Work space of Eliminate, kept to avoid allocations per block row.
  std::vector<Carry> carries_;
  Panel work_;
  std::vector<int> union_columns_;
  std::vector<int> merged_columns_;
  std::vector<int> union_in_row_;  // index in the R row's `right`, or -1
  std::vector<int> meeting_;       // carries whose leading column is the current row
  struct Run {                     // a carry's columns copied as one: scalar offsets, count
    int to, from, count;
  };
  std::vector<Run> runs_;
  // The block rows an elimination writes, before its commit: their positions, the rows
  // (storage reused between calls) and the (column, row) references of their new fill.
  std::vector<int> staged_positions_;
  std::vector<RBlockRow> staged_;
  std::vector<std::pair<int, int>> new_references_;
  std::vector<char> scratch_dirty_;
  InstanceId instance_id_;
  uint64_t revision_ = 0;
  std::vector<uint64_t> row_revision_;  // by block row: revision of its last change
  int64_t nonzeros_ = 0;
  int64_t eliminated_block_rows_ = 0;
  int64_t eliminated_block_columns_ = 0;
  int64_t eliminated_work_ = 0;
};

// Solves R^T y = g by block forward substitution, R given by its block rows and g indexed
// by position.
std::vector<Eigen::Vector3d> SolveTransposed(const std::vector<RBlockRow>& rows,
                                             std::vector<Eigen::Vector3d> g);

}  // namespace anchormap
