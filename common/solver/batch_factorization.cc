#include "common/solver/batch_factorization.h"

#include <algorithm>
#include <cmath>

#include <cholmod.h>

namespace anchormap {

// RAII around cholmod_common: CHOLMOD's workspace lives as long as the smoother.
struct BatchFactorization::Cholmod {
  cholmod_common common;
  Cholmod() {
    cholmod_start(&common);
    common.nmethods = 1;
    common.method[0].ordering = CHOLMOD_NATURAL;  // we order with CCOLAMD ourselves
    common.postorder = 0;
    common.supernodal = CHOLMOD_SIMPLICIAL;
    common.final_asis = 1;  // keep L D L^T: Factor() reads R = sqrt(D) L^T from it
    common.print = 0;
    common.error_handler = nullptr;
  }
  ~Cholmod() { cholmod_finish(&common); }
};

BatchFactorization::BatchFactorization() : cholmod_(std::make_unique<Cholmod>()) {}
BatchFactorization::~BatchFactorization() = default;

bool BatchFactorization::Factor(int n, const std::vector<PositionedFactor>& factors,
                                std::vector<RBlockRow>* rows, std::string* error) {
  // Normal equations by 3x3 blocks: upper triangle of A^T A by block column (flat arrays:
  // one counting pass, one filling pass, then sort and merge each column), and A^T b.
  std::vector<int> start(n + 1, 0);
  std::vector<Eigen::Vector3d> gradient(n, Eigen::Vector3d::Zero());
  auto for_each_pair = [](const PositionedFactor& f, auto&& visit) {
    for (int a = 0; a < f.num_keys; ++a) {
      for (int b = 0; b < f.num_keys; ++b) {
        if (f.positions[a] > f.positions[b]) continue;
        if (f.positions[a] == f.positions[b] && a > b) continue;  // repeated key: once per pair
        visit(a, b);
      }
    }
  };
  for (const PositionedFactor& f : factors) {
    for_each_pair(f, [&](int, int b) { ++start[f.positions[b] + 1]; });
  }
  for (int p = 0; p < n; ++p) start[p + 1] += start[p];
  std::vector<std::pair<int, Eigen::Matrix3d>> blocks(start[n]);
  {
    std::vector<int> next(start.begin(), start.end() - 1);
    for (const PositionedFactor& f : factors) {
      for (int a = 0; a < f.num_keys; ++a) {
        gradient[f.positions[a]].noalias() += f.jacobians[a].transpose() * f.rhs;
      }
      for_each_pair(f, [&](int a, int b) {
        Eigen::Matrix3d block = f.jacobians[a].transpose() * f.jacobians[b];
        if (f.positions[a] == f.positions[b] && a != b) block += block.transpose().eval();
        blocks[next[f.positions[b]]++] = {f.positions[a], block};
      });
    }
  }
  return FactorBlocks(n, start, std::move(blocks), std::move(gradient), rows, error);
}

bool BatchFactorization::FactorBlocks(int n, const std::vector<int>& start,
                                      std::vector<std::pair<int, Eigen::Matrix3d>> blocks,
                                      std::vector<Eigen::Vector3d> gradient,
                                      std::vector<RBlockRow>* rows, std::string* error) {
  cholmod_common* c = &cholmod_->common;
  // Per column: sum duplicates in place (a slot per row), then sort the (small) list of
  // rows, not the 80-byte entries; `column_rows[order[start[p] ..]]` gives column p's
  // `length[p]` blocks in row order.
  std::vector<int> length(n);
  std::vector<int> slot(n, -1);
  std::vector<int> order(blocks.size());
  size_t nnz = 0;
  for (int p = 0; p < n; ++p) {
    const int first = start[p];
    int out = first;
    for (int e = start[p]; e < start[p + 1]; ++e) {
      const int row = blocks[e].first;
      if (slot[row] >= 0) {
        blocks[slot[row]].second += blocks[e].second;
      } else {
        slot[row] = out;
        if (out != e) blocks[out] = blocks[e];
        ++out;
      }
    }
    length[p] = out - first;
    for (int e = first; e < out; ++e) {
      slot[blocks[e].first] = -1;
      order[e] = e;
    }
    std::sort(order.begin() + first, order.begin() + out,
              [&](int x, int y) { return blocks[x].first < blocks[y].first; });
    nnz += 9 * static_cast<size_t>(length[p]);
  }

  const size_t dim = 3 * static_cast<size_t>(n);
  cholmod_sparse* A = cholmod_allocate_sparse(dim, dim, nnz, 1, 1, 1, CHOLMOD_REAL, c);
  if (A == nullptr) {
    if (error)
      *error = "CHOLMOD could not allocate the normal equations (status " +
               std::to_string(c->status) + ")";
    return false;
  }
  auto* Ap = static_cast<int*>(A->p);
  auto* Ai = static_cast<int*>(A->i);
  auto* Ax = static_cast<double*>(A->x);
  size_t k = 0;
  for (int pb = 0; pb < n; ++pb) {
    for (int cb = 0; cb < 3; ++cb) {
      Ap[3 * pb + cb] = static_cast<int>(k);
      for (int e = start[pb]; e < start[pb] + length[pb]; ++e) {
        const auto& [pa, block] = blocks[order[e]];
        for (int ra = 0; ra < 3; ++ra) {
          if (pa == pb && ra > cb) break;
          Ai[k] = 3 * pa + ra;
          Ax[k] = block(ra, cb);
          ++k;
        }
      }
    }
  }
  Ap[dim] = static_cast<int>(k);

  // CHOLMOD's simplicial factorisation is L D L^T (unit-diagonal L, D first in each column);
  // R = sqrt(D) L^T is read from it directly, without CHOLMOD converting it to L L^T.
  cholmod_factor* L = cholmod_analyze(A, c);
  bool ok = L != nullptr && cholmod_factorize(A, L, c) && c->status == CHOLMOD_OK && !L->is_super;
  size_t failed_column = L ? L->minor : 0;
  if (ok) {
    const auto* Lp = static_cast<const int*>(L->p);
    const auto* Lx = static_cast<const double*>(L->x);
    for (size_t j = 0; j < dim && ok; ++j) {
      // LDL': D(j) > 0 and finite; LL': L(j,j) > 0. Either way the first entry of column j.
      const double pivot = Lx[Lp[j]];
      if (!(pivot > 0.0) || !std::isfinite(pivot)) {
        ok = false;
        failed_column = j;
      }
    }
  }
  if (!ok) {
    if (error) {
      *error = "batch factorisation failed (CHOLMOD status " + std::to_string(c->status) +
               "): the system is not positive definite at scalar column " +
               std::to_string(failed_column) + " (block " + std::to_string(failed_column / 3) +
               "); a variable is not constrained";
    }
    cholmod_free_factor(&L, c);
    cholmod_free_sparse(&A, c);
    return false;
  }

  // R row j (scalar) = column j of L^T: scale sqrt(D_j) for LDL' (unit diagonal implied).
  rows->assign(n, RBlockRow());
  const auto* Lp = static_cast<const int*>(L->p);
  const auto* Li = static_cast<const int*>(L->i);
  const auto* Lx = static_cast<const double*>(L->x);
  const auto* Lnz = static_cast<const int*>(L->nz);
  const bool is_ll = L->is_ll;
  std::vector<int> columns;
  for (int p = 0; p < n; ++p) {
    RBlockRow& row = (*rows)[p];
    // The blocks right of the diagonal: the pattern of scalar column 3p below its own
    // block (the pattern comes in 3x3 blocks), sorted as block columns.
    columns.clear();
    for (int e = Lp[3 * p] + 1; e < Lp[3 * p] + Lnz[3 * p]; ++e) {
      const int q = Li[e] / 3;
      if (q != p && slot[q] < 0) {
        slot[q] = 0;
        columns.push_back(q);
      }
    }
    std::sort(columns.begin(), columns.end());
    row.right.resize(columns.size());
    for (size_t k = 0; k < columns.size(); ++k) {
      slot[columns[k]] = static_cast<int>(k);
      row.right[k].first = columns[k];
      row.right[k].second.setZero();
    }
    for (int rj = 0; rj < 3; ++rj) {
      const int j = 3 * p + rj;
      const double scale = is_ll ? 1.0 : std::sqrt(Lx[Lp[j]]);
      row.diagonal(rj, rj) = is_ll ? Lx[Lp[j]] : scale;
      for (int e = Lp[j] + 1; e < Lp[j] + Lnz[j]; ++e) {
        const int i = Li[e];
        const int q = i / 3;
        const double value = scale * Lx[e];
        if (q == p) {
          row.diagonal(rj, i % 3) = value;
          continue;
        }
        if (slot[q] < 0) {  // not in column 3p's pattern (not expected): add it, sort later
          slot[q] = static_cast<int>(row.right.size());
          row.right.emplace_back(q, Eigen::Matrix3d::Zero());
        }
        row.right[slot[q]].second(rj, i % 3) = value;
      }
    }
    const bool sorted = row.right.size() == columns.size();
    for (const auto& [q, block] : row.right) slot[q] = -1;
    if (!sorted) {
      std::sort(row.right.begin(), row.right.end(),
                [](const auto& x, const auto& y) { return x.first < y.first; });
    }
  }
  cholmod_free_factor(&L, c);
  cholmod_free_sparse(&A, c);

  // d solves R^T d = A^T b.
  const std::vector<Eigen::Vector3d> d = SolveTransposed(*rows, std::move(gradient));
  for (int p = 0; p < n; ++p) (*rows)[p].rhs = d[p];
  return true;
}

}  // namespace anchormap
