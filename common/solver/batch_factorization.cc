#include "common/solver/batch_factorization.h"

#include <algorithm>

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
    common.final_ll = 1;
    common.print = 0;
    common.error_handler = nullptr;
  }
  ~Cholmod() { cholmod_finish(&common); }
};

BatchFactorization::BatchFactorization() : cholmod_(std::make_unique<Cholmod>()) {}
BatchFactorization::~BatchFactorization() = default;

bool BatchFactorization::Factor(int n, const std::vector<PositionedFactor>& factors,
                                std::vector<RBlockRow>* rows, std::string* error) {
  cholmod_common* c = &cholmod_->common;

  // Normal equations by 3x3 blocks: upper triangle of A^T A by block column, and A^T b.
  std::vector<std::vector<std::pair<int, Eigen::Matrix3d>>> columns(n);
  std::vector<Eigen::Vector3d> gradient(n, Eigen::Vector3d::Zero());
  for (const PositionedFactor& f : factors) {
    for (int a = 0; a < f.num_keys; ++a) {
      gradient[f.positions[a]].noalias() += f.jacobians[a].transpose() * f.rhs;
      for (int b = 0; b < f.num_keys; ++b) {
        if (f.positions[a] > f.positions[b]) continue;
        if (f.positions[a] == f.positions[b] && a > b) continue;  // repeated key: once per pair
        Eigen::Matrix3d block = f.jacobians[a].transpose() * f.jacobians[b];
        if (f.positions[a] == f.positions[b] && a != b) block += block.transpose().eval();
        columns[f.positions[b]].emplace_back(f.positions[a], block);
      }
    }
  }
  size_t nnz = 0;
  for (auto& column : columns) {
    std::sort(column.begin(), column.end(),
              [](const auto& x, const auto& y) { return x.first < y.first; });
    size_t out = 0;
    for (size_t k = 0; k < column.size(); ++k) {
      if (out > 0 && column[out - 1].first == column[k].first) {
        column[out - 1].second += column[k].second;
      } else {
        column[out++] = column[k];
      }
    }
    column.resize(out);
    nnz += 9 * out;
  }

  const size_t dim = 3 * static_cast<size_t>(n);
  cholmod_sparse* A = cholmod_allocate_sparse(dim, dim, nnz, 1, 1, 1, CHOLMOD_REAL, c);
  auto* Ap = static_cast<int*>(A->p);
  auto* Ai = static_cast<int*>(A->i);
  auto* Ax = static_cast<double*>(A->x);
  size_t k = 0;
  for (int pb = 0; pb < n; ++pb) {
    for (int cb = 0; cb < 3; ++cb) {
      Ap[3 * pb + cb] = static_cast<int>(k);
      for (const auto& [pa, block] : columns[pb]) {
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

  cholmod_factor* L = cholmod_analyze(A, c);
  bool ok = L != nullptr && cholmod_factorize(A, L, c) && c->status == CHOLMOD_OK;
  if (ok) ok = cholmod_change_factor(CHOLMOD_REAL, 1, 0, 1, 1, L, c) && L->is_ll;
  if (!ok) {
    if (error) {
      const size_t minor = L ? L->minor : 0;
      *error = "batch factorisation failed (CHOLMOD status " + std::to_string(c->status) +
               "): the system is not positive definite at scalar column " + std::to_string(minor) +
               " (block " + std::to_string(minor / 3) + "); a variable is not constrained";
    }
    cholmod_free_factor(&L, c);
    cholmod_free_sparse(&A, c);
    return false;
  }

  // R = L^T: scalar column j of L is scalar row j of R.
  rows->assign(n, RBlockRow());
  const auto* Lp = static_cast<const int*>(L->p);
  const auto* Li = static_cast<const int*>(L->i);
  const auto* Lx = static_cast<const double*>(L->x);
  const auto* Lnz = static_cast<const int*>(L->nz);
  std::vector<int> slot(n, -1);
  for (int p = 0; p < n; ++p) {
    RBlockRow& row = (*rows)[p];
    for (int rj = 0; rj < 3; ++rj) {
      const int j = 3 * p + rj;
      for (int e = Lp[j]; e < Lp[j] + Lnz[j]; ++e) {
        const int i = Li[e];
        const int q = i / 3;
        if (q == p) {
          row.diagonal(rj, i % 3) = Lx[e];
          continue;
        }
        if (slot[q] < 0) {
          slot[q] = static_cast<int>(row.right.size());
          row.right.emplace_back(q, Eigen::Matrix3d::Zero());
        }
        row.right[slot[q]].second(rj, i % 3) = Lx[e];
      }
    }
    for (const auto& [q, block] : row.right) slot[q] = -1;
    std::sort(row.right.begin(), row.right.end(),
              [](const auto& x, const auto& y) { return x.first < y.first; });
  }
  cholmod_free_factor(&L, c);
  cholmod_free_sparse(&A, c);

  // d solves R^T d = A^T b.
  const std::vector<Eigen::Vector3d> d = SolveTransposed(*rows, std::move(gradient));
  for (int p = 0; p < n; ++p) (*rows)[p].rhs = d[p];
  return true;
}

}  // namespace anchormap
