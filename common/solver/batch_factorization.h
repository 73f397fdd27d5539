#pragma once
// A batch step's factorisation: forms the normal equations A^T A, A^T b of all
// linearised factors in a given variable order, factors them with CHOLMOD (no further
// permutation) and returns R and d with R^T R = A^T A, R^T d = A^T b, so that the
// incremental updates continue from it exactly as from a QR factorisation of A.
// Small or sparse systems are factored simplicially (L D L^T, R = sqrt(D) L^T); those with
// many flops per non-zero of L (a large dense root: late multi-robot maps) supernodally
// (L L^T, R = L^T), on the single-threaded OpenBLAS the build links (see CMakeLists.txt).

#include <memory>
#include <string>
#include <vector>

#include "common/solver/sparse_r.h"

namespace anchormap {

// One linearised factor, with its variables already mapped to elimination positions.
struct PositionedFactor {
  int num_keys = 0;
  int positions[4] = {0, 0, 0, 0};
  const Eigen::Matrix3d* jacobians = nullptr;  // num_keys whitened blocks
  Eigen::Vector3d rhs;                         // -whitened error
};

class BatchFactorization {
 public:
  // CHOLMOD factors supernodally when its analysis counts at least `supernodal_switch`
  // flops per non-zero of L. The default is where supernodal on OpenBLAS overtakes
  // simplicial (measured on the normal equations of 20-robot and city10000 batch steps:
  // docs/ARCHITECTURE.md, blas23); 0 makes every factorisation supernodal.
  static constexpr double kSupernodalSwitch = 200.0;
  explicit BatchFactorization(double supernodal_switch = kSupernodalSwitch);
  ~BatchFactorization();
  BatchFactorization(const BatchFactorization&) = delete;
  BatchFactorization& operator=(const BatchFactorization&) = delete;

  // Factors the system of `factors` over `num_positions` variables. On success fills
  // `rows` (R and d by block row) and returns true; on failure (matrix not positive
  // definite: an unconstrained variable) returns false and sets `error`.
  bool Factor(int num_positions, const std::vector<PositionedFactor>& factors,
              std::vector<RBlockRow>* rows, std::string* error);

  // The same from normal equations grouped by column (the core of Factor; the partial
  // step gives its blocks directly):
  // `blocks[start[q] .. start[q+1])` are column q's (p, H_pq) entries, p <= q, in any order
  // (duplicates are summed).
  bool FactorBlocks(int n, const std::vector<int>& start,
                    std::vector<std::pair<int, Eigen::Matrix3d>> blocks,
                    std::vector<Eigen::Vector3d> gradient, std::vector<RBlockRow>* rows,
                    std::string* error);

  // How many factorisations so far were supernodal.
  int supernodal_factorizations() const { return supernodal_factorizations_; }

 private:
  struct Cholmod;
  std::unique_ptr<Cholmod> cholmod_;
  int supernodal_factorizations_ = 0;
};

}  // namespace anchormap
