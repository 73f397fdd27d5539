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
  auto by_column = [](const auto& x, const auto& y) { return x.first < y.first; };
  std::sort(rows.blocks.begin(), rows.blocks.end(), by_column);
  std::vector<std::pair<int, Eigen::Matrix3d>>& next_blocks = scratch_blocks_;
  std::vector<int>& columns = scratch_columns_;
  Eigen::Matrix<double, 6, Eigen::Dynamic, Eigen::RowMajor>& W = scratch_;

  while (!rows.blocks.empty()) {
    const int c = rows.blocks.front().first;
    RBlockRow& row = rows_[c];
    if (touched) touched->push_back(c);
    const bool was_empty = row.diagonal.isZero(0.0) && row.right.empty();

    // Union of the columns right of c in R's row and in the new rows (both sorted).
    columns.clear();
    {
      auto r = row.right.begin();
      auto n = rows.blocks.begin() + 1;
      while (r != row.right.end() || n != rows.blocks.end()) {
        if (n == rows.blocks.end() || (r != row.right.end() && r->first < n->first)) {
          columns.push_back((r++)->first);
        } else if (r == row.right.end() || n->first < r->first) {
          columns.push_back((n++)->first);
        } else {
          columns.push_back(r->first);
          ++r;
          ++n;
        }
      }
    }
    const int m = static_cast<int>(columns.size());
    ++eliminated_block_rows_;
    eliminated_block_columns_ += m + 1;
    if (W.cols() < 3 + 3 * m + 1) W.resize(6, 2 * (3 + 3 * m + 1));  // amortised growth
    const int width = 3 + 3 * m + 1;
    W.leftCols(width).setZero();
    W.block<3, 3>(0, 0) = row.diagonal;
    W.block<3, 3>(3, 0) = rows.blocks.front().second;
    {
      int k = 0;
      for (const auto& [q, block] : row.right) {
        while (columns[k] != q) ++k;
        W.block<3, 3>(0, 3 + 3 * k) = block;
      }
      k = 0;
      for (auto n = rows.blocks.begin() + 1; n != rows.blocks.end(); ++n) {
        while (columns[k] != n->first) ++k;
        W.block<3, 3>(3, 3 + 3 * k) = n->second;
      }
    }
    W.block<3, 1>(0, 3 + 3 * m) = row.rhs;
    W.block<3, 1>(3, 3 + 3 * m) = rows.rhs;

    // Zero the new rows' entries under the diagonal block.
    EliminateBlockRow(W.data(), static_cast<int>(W.cols()), width);

    // Write back R's row (new fill registers in the column index) and the new rows.
    const size_t old_right = row.right.size();
    if (static_cast<size_t>(m) != old_right) {
      for (int k = 0, r = 0; k < m; ++k) {
        if (r < static_cast<int>(old_right) && row.right[r].first == columns[k]) {
          ++r;
        } else {
          column_rows_[columns[k]].push_back(c);
        }
      }
    }
    row.diagonal = W.block<3, 3>(0, 0);
    row.right.resize(m);
    next_blocks.clear();
    for (int k = 0; k < m; ++k) {
      row.right[k] = {columns[k], W.block<3, 3>(0, 3 + 3 * k)};
      const Eigen::Matrix3d low = W.block<3, 3>(3, 3 + 3 * k);
      if (!low.isZero(0.0)) next_blocks.emplace_back(columns[k], low);
    }
    row.rhs = W.block<3, 1>(0, 3 + 3 * m);
    rows.rhs = W.block<3, 1>(3, 3 + 3 * m);
    nonzeros_ +=
        kBlockNonZeros * static_cast<int64_t>(m - old_right) + (was_empty ? kDiagonalNonZeros : 0);
    rows.blocks.swap(next_blocks);
  }
  return rows.rhs.squaredNorm();
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
