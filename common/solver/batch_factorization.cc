#include "common/solver/batch_factorization.h"

#include <algorithm>
#include <cmath>

#include <cholmod.h>

namespace anchormap {

namespace {

// Scalar column j of CHOLMOD's factor, simplicial (L D L^T or L L^T) or supernodal (L L^T),
// as R's row j: visit(i, R_ji) for each stored entry, the diagonal first. Columns are
// visited in increasing order (the supernode is found by walking forward).
class ColumnReader {
 public:
  explicit ColumnReader(const cholmod_factor* L)
      : L_(L),
        p_(static_cast<const int*>(L->p)),
        i_(static_cast<const int*>(L->is_super ? L->s : L->i)),
        nz_(static_cast<const int*>(L->nz)),
        x_(static_cast<const double*>(L->x)),
        super_(static_cast<const int*>(L->super)),
        pi_(static_cast<const int*>(L->pi)),
        px_(static_cast<const int*>(L->px)) {}

  // D_j (L D L^T) or L_jj (L L^T).
  double Pivot(int j) {
    if (!L_->is_super) return x_[p_[j]];
    while (super_[s_ + 1] <= j) ++s_;
    const int local = j - super_[s_];
    return x_[px_[s_] + static_cast<size_t>(local) * (pi_[s_ + 1] - pi_[s_]) + local];
  }

  template <typename Visit>
  void ForEach(int j, Visit&& visit) {
    if (L_->is_super) {
      while (super_[s_ + 1] <= j) ++s_;
      const int rows = pi_[s_ + 1] - pi_[s_];
      const int local = j - super_[s_];
      const int* index = i_ + pi_[s_];
      const double* value = x_ + px_[s_] + static_cast<size_t>(local) * rows;
      for (int e = local; e < rows; ++e) visit(index[e], value[e]);
      return;
    }
    const int first = p_[j];
    const int last = first + nz_[j];
    // L D L^T: R_jj = sqrt(D_j), R_ji = sqrt(D_j) L_ij; L L^T: R_ji = L_ij.
    const double scale = L_->is_ll ? 1.0 : std::sqrt(x_[first]);
    visit(i_[first], L_->is_ll ? x_[first] : scale);
    for (int e = first + 1; e < last; ++e) visit(i_[e], scale * x_[e]);
  }

 private:
  const cholmod_factor* L_;
  const int* p_;
  const int* i_;
  const int* nz_;
  const double* x_;
  const int* super_;
  const int* pi_;
  const int* px_;
  size_t s_ = 0;
};

// R's block rows from L. Simplicial: the off-diagonal blocks are the pattern of scalar
// column 3p below its diagonal block (the pattern comes in 3x3 blocks). Supernodal: relaxed
// supernodes also store rows that are structurally zero (exactly 0 after the factorisation:
// every update to them is a product with a structural zero); blocks whose entries are all
// zero are dropped, and the count left must be column 3p's structural count (`ColCount`),
// else false (a structurally non-zero block that is numerically zero: the caller factors
// again simplicially). `slot` is n entries of -1 (restored).
bool ReadRows(const cholmod_factor* L, int n, bool drop_zero_blocks, std::vector<int>* slot_in,
              std::vector<RBlockRow>* rows) {
  std::vector<int>& slot = *slot_in;
  const auto* colcount = static_cast<const int*>(L->ColCount);
  ColumnReader column(L);
  rows->assign(n, RBlockRow());
  std::vector<int> columns;
  for (int p = 0; p < n; ++p) {
    RBlockRow& row = (*rows)[p];
    columns.clear();
    column.ForEach(3 * p, [&](int i, double) {
      const int q = i / 3;
      if (q != p && slot[q] < 0) {
        slot[q] = 0;
        columns.push_back(q);
      }
    });
    std::sort(columns.begin(), columns.end());
    row.right.resize(columns.size());
    for (size_t k = 0; k < columns.size(); ++k) {
      slot[columns[k]] = static_cast<int>(k);
      row.right[k].first = columns[k];
      row.right[k].second.setZero();
    }
    for (int rj = 0; rj < 3; ++rj) {
      column.ForEach(3 * p + rj, [&](int i, double value) {
        const int q = i / 3;
        if (q == p) {
          row.diagonal(rj, i % 3) = value;
          return;
        }
        if (slot[q] < 0) {  // not in column 3p's pattern (not expected): add it, sort later
          slot[q] = static_cast<int>(row.right.size());
          row.right.emplace_back(q, Eigen::Matrix3d::Zero());
        }
        row.right[slot[q]].second(rj, i % 3) = value;
      });
    }
    const bool sorted = row.right.size() == columns.size();
    for (const auto& [q, block] : row.right) slot[q] = -1;
    if (!sorted) {
      std::sort(row.right.begin(), row.right.end(),
                [](const auto& x, const auto& y) { return x.first < y.first; });
    }
    if (drop_zero_blocks) {
      row.right.erase(std::remove_if(row.right.begin(), row.right.end(),
                                     [](const auto& entry) { return entry.second.isZero(0.0); }),
                      row.right.end());
      if (3 * row.right.size() + 3 != static_cast<size_t>(colcount[3 * p])) return false;
    }
  }
  return true;
}

}  // namespace

// RAII around cholmod_common: CHOLMOD's workspace lives as long as the smoother.
struct BatchFactorization::Cholmod {
  cholmod_common common;
  explicit Cholmod(double supernodal_switch) {
    cholmod_start(&common);
    common.nmethods = 1;
    common.method[0].ordering = CHOLMOD_NATURAL;  // we order with CCOLAMD ourselves
    common.postorder = 0;
    common.supernodal = CHOLMOD_AUTO;
    common.supernodal_switch = supernodal_switch;
    common.final_asis = 1;  // keep the factor as computed: Factor() reads R from either form
    common.print = 0;
    common.error_handler = nullptr;
  }
  ~Cholmod() { cholmod_finish(&common); }
};

BatchFactorization::BatchFactorization(double supernodal_switch)
    : cholmod_(std::make_unique<Cholmod>(supernodal_switch)) {}
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

  // CHOLMOD chooses by the analysis' flops per non-zero of L (`supernodal_switch`):
  // simplicial L D L^T below it, R = sqrt(D) L^T read directly without converting to L L^T;
  // supernodal L L^T (dense BLAS kernels on the fronts) above it, R = L^T read from the
  // supernodes.
  cholmod_factor* L = cholmod_analyze(A, c);
  bool ok =
      L != nullptr && cholmod_factorize(A, L, c) && c->status == CHOLMOD_OK && L->minor == dim;
  size_t failed_column = L ? L->minor : 0;
  if (ok) {
    ColumnReader column(L);
    for (size_t j = 0; j < dim && ok; ++j) {
      // LDL': D(j) > 0 and finite; LL': L(j,j) > 0. Either way the first entry of column j.
      const double pivot = column.Pivot(static_cast<int>(j));
      if (!(pivot > 0.0) || !std::isfinite(pivot)) {
        ok = false;
        failed_column = j;
      }
    }
  }
  if (ok && L->is_super) {
    ok = ReadRows(L, n, true, &slot, rows);
    if (ok) ++supernodal_factorizations_;
  }
  if (!ok && L != nullptr && L->is_super && failed_column == dim) {
    // A supernodal factor whose non-zero blocks do not match its structure (not expected):
    // factor again simplicially, whose pattern is the structure itself.
    cholmod_free_factor(&L, c);
    const int supernodal = c->supernodal;
    c->supernodal = CHOLMOD_SIMPLICIAL;
    L = cholmod_analyze(A, c);
    c->supernodal = supernodal;
    ok = L != nullptr && cholmod_factorize(A, L, c) && c->status == CHOLMOD_OK && L->minor == dim;
    failed_column = L ? L->minor : 0;
  }
  if (ok && !L->is_super) ok = ReadRows(L, n, false, &slot, rows);
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
  cholmod_free_factor(&L, c);
  cholmod_free_sparse(&A, c);

  // d solves R^T d = A^T b.
  const std::vector<Eigen::Vector3d> d = SolveTransposed(*rows, std::move(gradient));
  for (int p = 0; p < n; ++p) (*rows)[p].rhs = d[p];
  return true;
}

}  // namespace anchormap
