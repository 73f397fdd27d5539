#include "common/solver/sparse_r.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include <Eigen/Dense>

#include "common/solver/block_givens.h"

namespace anchormap {
namespace {

constexpr int64_t kDiagonalNonZeros = 6;
constexpr int64_t kBlockNonZeros = 9;

}  // namespace

void SparseR::Append(int count) {
  rows_.resize(rows_.size() + count);
  column_rows_.resize(rows_.size());
}

void SparseR::Assign(std::vector<RBlockRow> rows) {
  rows_ = std::move(rows);
  column_rows_.assign(rows_.size(), {});
  nonzeros_ = 0;
  for (int p = 0; p < size(); ++p) {
    nonzeros_ += kDiagonalNonZeros + kBlockNonZeros * static_cast<int64_t>(rows_[p].right.size());
    for (const auto& [q, block] : rows_[p].right) column_rows_[q].push_back(p);
  }
}

double SparseR::Eliminate(NewRows rows, std::vector<int>* touched) {
  // The new rows, as a row-major panel by sorted column (a key repeated within one
  // measurement has its blocks summed).
  auto by_column = [](const auto& x, const auto& y) { return x.first < y.first; };
  std::sort(rows.blocks.begin(), rows.blocks.end(), by_column);
  carry_columns_.clear();
  for (const auto& [q, block] : rows.blocks) {
    if (carry_columns_.empty() || carry_columns_.back() != q) carry_columns_.push_back(q);
  }
  const int initial = static_cast<int>(carry_columns_.size());
  if (carry_.cols() < 3 * initial + 1) carry_.resize(3, 2 * (3 * initial + 1));
  carry_.leftCols(3 * initial + 1).setZero();
  for (size_t b = 0, k = 0; b < rows.blocks.size(); ++b) {
    while (carry_columns_[k] != rows.blocks[b].first) ++k;
    carry_.block(0, 3 * k, 3, 3) += rows.blocks[b].second;
  }
  carry_.col(3 * initial) = rows.rhs;

  while (!carry_columns_.empty()) {
    const int c = carry_columns_.front();
    RBlockRow& row = rows_[c];
    if (touched) touched->push_back(c);
    const bool was_empty = row.diagonal.isZero(0.0) && row.right.empty();

    // Union of the columns right of c in R's row and in the carried rows (both sorted),
    // remembering where each came from.
    union_.clear();
    {
      const int nr = static_cast<int>(row.right.size());
      const int nc = static_cast<int>(carry_columns_.size());
      int r = 0, n = 1;
      while (r < nr || n < nc) {
        if (n == nc || (r < nr && row.right[r].first < carry_columns_[n])) {
          union_.push_back({row.right[r].first, r, -1});
          ++r;
        } else if (r == nr || carry_columns_[n] < row.right[r].first) {
          union_.push_back({carry_columns_[n], -1, n});
          ++n;
        } else {
          union_.push_back({carry_columns_[n], r, n});
          ++r;
          ++n;
        }
      }
    }
    const int m = static_cast<int>(union_.size());
    ++eliminated_block_rows_;
    eliminated_block_columns_ += m + 1;
    const int width = 3 + 3 * m + 1;
    if (work_.cols() < width) work_.resize(6, 2 * width);  // amortised growth
    const int carry_rhs = 3 * static_cast<int>(carry_columns_.size());

    // Rows 0-2: R's row; rows 3-5: the carried rows. Each block is written once (zeros
    // where one side has no block), so the panel needs no clearing.
    for (int i = 0; i < 3; ++i) {
      double* upper = work_.row(i).data();
      double* lower = work_.row(3 + i).data();
      const double* carried = carry_.row(i).data();
      for (int j = 0; j < 3; ++j) {
        upper[j] = row.diagonal(i, j);
        lower[j] = carried[j];
      }
      for (int k = 0; k < m; ++k) {
        const UnionColumn& u = union_[k];
        double* up = upper + 3 + 3 * k;
        double* low = lower + 3 + 3 * k;
        if (u.in_row >= 0) {
          const Eigen::Matrix3d& block = row.right[u.in_row].second;
          up[0] = block(i, 0);
          up[1] = block(i, 1);
          up[2] = block(i, 2);
        } else {
          up[0] = up[1] = up[2] = 0.0;
        }
        if (u.in_carry >= 0) {
          const double* from = carried + 3 * u.in_carry;
          low[0] = from[0];
          low[1] = from[1];
          low[2] = from[2];
        } else {
          low[0] = low[1] = low[2] = 0.0;
        }
      }
      upper[width - 1] = row.rhs(i);
      lower[width - 1] = carried[carry_rhs];
    }

    // Zero the carried rows under the diagonal block.
    EliminateBlockRow(work_.data(), static_cast<int>(work_.cols()), width);

    // Write back R's row (new fill registers in the column index).
    const size_t old_right = row.right.size();
    if (static_cast<size_t>(m) != old_right) {
      for (const UnionColumn& u : union_) {
        if (u.in_row < 0) column_rows_[u.column].push_back(c);
      }
    }
    row.diagonal = work_.block<3, 3>(0, 0);
    row.right.resize(m);
    for (int k = 0; k < m; ++k) {
      row.right[k].first = union_[k].column;
      row.right[k].second = work_.block<3, 3>(0, 3 + 3 * k);
    }
    row.rhs = work_.block<3, 1>(0, width - 1);
    nonzeros_ +=
        kBlockNonZeros * static_cast<int64_t>(m - old_right) + (was_empty ? kDiagonalNonZeros : 0);

    // The carried rows for the next block row: every column where they are not all zero.
    next_carry_columns_.clear();
    if (next_carry_.cols() < 3 * m + 1) next_carry_.resize(3, 2 * (3 * m + 1));
    for (int k = 0; k < m; ++k) {
      const auto low = work_.block<3, 3>(3, 3 + 3 * k);
      if (low.isZero(0.0)) continue;
      next_carry_.block<3, 3>(0, 3 * static_cast<int>(next_carry_columns_.size())) = low;
      next_carry_columns_.push_back(union_[k].column);
    }
    next_carry_.block<3, 1>(0, 3 * static_cast<int>(next_carry_columns_.size())) =
        work_.block<3, 1>(3, width - 1);
    carry_.swap(next_carry_);
    carry_columns_.swap(next_carry_columns_);
  }
  return carry_.block<3, 1>(0, 0).squaredNorm();
}

Eigen::Vector3d SparseR::SolveRow(int p, const std::vector<Eigen::Vector3d>& delta) const {
  const RBlockRow& row = rows_[p];
  Eigen::Vector3d v = row.rhs;
  for (const auto& [q, block] : row.right) v.noalias() -= block * delta[q];
  return row.diagonal.triangularView<Eigen::Upper>().solve(v);
}

void SparseR::BackSubstitute(std::vector<Eigen::Vector3d>* delta) const {
  delta->resize(rows_.size());
  for (int p = size() - 1; p >= 0; --p) (*delta)[p] = SolveRow(p, *delta);
}

int SparseR::BackSubstitutePartial(const std::vector<int>& dirty, double threshold,
                                   std::vector<Eigen::Vector3d>* delta) {
  delta->resize(rows_.size(), Eigen::Vector3d::Zero());
  // Rows are solved in decreasing position; a row only ever marks rows above it, so one
  // downward sweep over a bitmap visits each dirty row once (cheaper than a heap).
  std::vector<char>& mark = scratch_dirty_;
  mark.assign(rows_.size(), 0);
  int highest = -1;
  for (int p : dirty) {
    mark[p] = 1;
    highest = std::max(highest, p);
  }
  int recomputed = 0;
  for (int p = highest; p >= 0; --p) {
    if (!mark[p]) continue;
    const Eigen::Vector3d value = SolveRow(p, *delta);
    const double change = (value - (*delta)[p]).cwiseAbs().maxCoeff();
    (*delta)[p] = value;
    ++recomputed;
    if (change > threshold) {
      for (int r : column_rows_[p]) mark[r] = 1;
    }
  }
  return recomputed;
}

double SparseR::MinAbsDiagonal() const {
  double smallest = std::numeric_limits<double>::infinity();
  for (const RBlockRow& row : rows_) {
    smallest = std::min(smallest, row.diagonal.diagonal().cwiseAbs().minCoeff());
  }
  return smallest;
}

std::vector<Eigen::Vector3d> SolveTransposed(const std::vector<RBlockRow>& rows,
                                             std::vector<Eigen::Vector3d> g) {
  // R^T y = g: block row p of R^T is column p of R, so process positions upwards and
  // push each solved y_p into the later entries it touches.
  for (size_t p = 0; p < rows.size(); ++p) {
    g[p] = rows[p].diagonal.transpose().triangularView<Eigen::Lower>().solve(g[p]);
    for (const auto& [q, block] : rows[p].right) g[q].noalias() -= block.transpose() * g[p];
  }
  return g;
}

}  // namespace anchormap
