#pragma once
// The correction's chi2 and half-gradient g = sum_k J_k^T e_k at the estimate
// (smoother_correction.cc), kept between passes. A pass linearises only the factors one of
// whose variables moved (LinearizationCache), and adds again only the sums those factors
// feed: g at each of their variables, and chi2 from the first of them on. Right after an
// update only the new factors are new, so its first pass costs them, not the map.
//
// The sums are the bits of a full pass: g at a variable adds its factors' terms J_k^T e_k
// in factor id order starting from zero, chi2 adds the factors' squared errors in id order
// (kept as a prefix by factor id). So a pass is a pure function of the values and the
// factors, whatever the passes before it: a smoother restored from a snapshot (which
// starts with an empty one) continues bit for bit.

#include <array>
#include <cstdint>
#include <vector>

#include <Eigen/Core>

#include "common/geometry/pose2.h"
#include "common/solver/factor.h"
#include "common/solver/factor_record.h"
#include "common/solver/linearization_cache.h"

namespace anchormap {

class IncrementalGradient {
 public:
  // One pass at `values` (by variable). g is ordered by `position_to_var` (the variables
  // in R); `counted` (by factor id) says which of `factors` count (active, rows in R; all
  // their variables are in R); `var_factors` lists each variable's factor ids ascending.
  // Returns chi2; g() holds the half-gradient by position until the next pass.
  double Pass(const std::vector<Pose2>& values, const std::vector<int>& position_to_var,
              const std::vector<smoother_internal::FactorRecord>& factors,
              const std::vector<char>& counted,
              const std::vector<std::vector<int64_t>>& var_factors);
  const std::vector<Eigen::Vector3d>& g() const { return g_; }
  // q = J^T J p, J the factors the last pass counted, linearised there, by blocks (J^T J is
  // never formed); p and q by position, q zeroed first. Returns |J p|^2. The conjugate
  // gradients' product: factor by factor in id order, reading each entry where the pass
  // left it.
  double MultiplyNormal(const std::vector<Eigen::Vector3d>& p,
                        std::vector<Eigen::Vector3d>* q) const;
  // Forgets everything: the next pass is a full one.
  void Clear();

  // Work counters: passes and factors linearised by them.
  int64_t passes() const { return cache_.passes(); }
  int64_t linearized() const { return cache_.linearized(); }

 private:
  // Factor id's term J_k^T e at its key k.
  Eigen::Map<Eigen::Vector3d> Term(int64_t id, int k) {
    return Eigen::Map<Eigen::Vector3d>(terms_.data() + term_offset_[id] + 3 * k);
  }
  // g at `position` again from the terms of its variable's counted factors.
  void SumAt(int var, const std::vector<std::vector<int64_t>>& var_factors);

  LinearizationCache cache_;
  // By factor id.
  std::vector<std::array<int, kMaxFactorKeys>> factor_vars_;
  std::vector<int> factor_num_vars_;
  std::vector<char> counted_;  // counted by the last pass
  // Its variables' positions in g, valid while counted (the conjugate gradients' J p and the
  // full scatter of g read them without going through the variables).
  std::vector<std::array<int, kMaxFactorKeys>> positions_;
  std::vector<char> stale_;  // work space: a variable of it moved in this pass
  // J_k^T e by key, at the last pass's values, packed: factor id's 3 x num_vars doubles
  // from term_offset_[id].
  std::vector<double> terms_;
  std::vector<int64_t> term_offset_;
  std::vector<double> squared_;      // |e|^2, same
  std::vector<double> chi2_prefix_;  // sum of the counted |e|^2 up to and including it
  // By variable.
  std::vector<int> position_;  // in g, -1 outside R (as of the last pass)
  std::vector<char> dirty_;    // work space: its g must be added again
  std::vector<int> dirty_vars_;
  // By position.
  std::vector<int> order_;  // position_to_var of the last pass
  std::vector<Eigen::Vector3d> g_;
};

}  // namespace anchormap
